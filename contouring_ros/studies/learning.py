"""Passes of a learning experiment: with ``/ccc.type: ilc`` and ``passes: N`` the path is run N times, each
pass a run of its own (a bag through the graph, or in-process), and the correction learned from one pass
(:func:`contouring_ros.core.ilc.learn`) is what the next plays back.

Through the graph, pass j + 1 reads its correction from ``learned_file``: the .npy file written next to the
bags (``<bag stem>_pass<j+1>_learned.npy``, beside ``<bag stem>_pass<j+1>.mcap``), so that every pass can be
run again from its bag's experiment and that file. In-process, each pass's loop gets the table directly; the
numbers are the same as the graph's (a bag reads back the floats the simulation computed).
"""
from __future__ import annotations

import dataclasses
import tempfile
from pathlib import Path

import numpy as np

from ..core.ilc import learn
from ..core.simulation import first_divergence, path_bound, simulate
from ..records.outputs import write_atomically
from ..experiment.build import build_loop
from ..experiment.model import Experiment
from ..experiment.schema import SEED_RANGE
from ..records.scoring import read_run
from .sweep import simulate_loops
from ..experiment.settings import written_settings

__all__ = ["passes", "next_correction", "pass_settings", "pass_experiment", "simulate_passes",
           "simulate_last_passes", "pass_bag", "run_passes"]

PASS_SEED_STRIDE = 104_729      # a prime, far from the seeds the benchmark's draws use (1 + 16 j + axis)


def passes(experiment: Experiment) -> int:
    """How many passes the experiment runs (its controller's ``passes``; 1 for every other controller)."""
    return int(experiment.controller.get("passes", 1) or 1) if experiment.controller.get("type") == "ilc" else 1


def next_correction(experiment: Experiment, result, correction) -> np.ndarray:
    """The correction the pass after the one that gave ``result`` (playing back ``correction``) plays back."""
    section = experiment.controller
    return learn(correction, result.reference_position, result.position, result.estimate_vector,
                 experiment.sample_time, section["gamma_tracking"], section["gamma_contour"], section["lead"],
                 section["q_cutoff"])


def _pass_seeds(experiment: Experiment, j: int) -> list:
    """(axis, plant key, seed) that give pass ``j`` its own noise: each plant's ``noise_seed`` and a random
    disturbance's ``seed`` (key ``disturbance.seed``) moved by (j - 1) x PASS_SEED_STRIDE, within the seeds a
    file may hold (SEED_RANGE); none for pass 1."""
    if j <= 1:
        return []
    def moved(seed) -> int:
        return (int(seed or 0) + (j - 1) * PASS_SEED_STRIDE) % (SEED_RANGE[1] + 1)
    out = []
    for axis, plant in experiment.plants.items():
        out.append((axis, "noise_seed", moved(plant.get("noise_seed", 0))))
        disturbance = plant.get("disturbance") or {}
        if disturbance.get("type") == "random":
            out.append((axis, "disturbance.seed", moved(disturbance.get("seed", 0))))
    return out


def pass_settings(experiment: Experiment, j: int) -> dict:
    """Pass ``j``'s seeds (:func:`_pass_seeds`) as grid keys (``x/plant.noise_seed``), for the file a graph
    run of the pass reads."""
    return {f"{axis}/plant.{key}": seed for axis, key, seed in _pass_seeds(experiment, j)}


def pass_experiment(experiment: Experiment, j: int) -> Experiment:
    """``experiment`` with pass ``j``'s seeds (:func:`_pass_seeds`)."""
    seeds = _pass_seeds(experiment, j)
    if not seeds:
        return experiment
    plants = {axis: dict(plant) for axis, plant in experiment.plants.items()}
    for axis, key, seed in seeds:
        if key == "disturbance.seed":
            plants[axis]["disturbance"] = {**plants[axis]["disturbance"], "seed": seed}
        else:
            plants[axis][key] = seed
    return dataclasses.replace(experiment, plants=plants)


def simulate_passes(experiment: Experiment, progress=None) -> list:
    """(loop, result) of every pass, in-process (a diverged pass raises Diverged, as one run does)."""
    out, table, last = [], None, passes(experiment)
    for j in range(1, last + 1):
        loop = build_loop(pass_experiment(experiment, j))
        if table is not None:
            loop.controller.table = table
        result = simulate(loop)
        out.append((loop, result))
        if progress is not None:
            progress(j, loop, result)
        if j < last:
            table = next_correction(experiment, result, table)
    return out


def simulate_last_passes(experiments: list) -> list:
    """(loop, result, failure) of each experiment's last pass, in-process: pass j of every experiment still
    running advances together (:func:`contouring_ros.studies.sweep.simulate_loops`: one vectorised batch where
    their classes allow, as a sweep's runs), each learning from its own pass as :func:`simulate_passes`
    does. A pass that diverges ends its experiment: (its loop, None, how it diverged)."""
    out, tables = [None] * len(experiments), [None] * len(experiments)
    running = list(range(len(experiments)))
    j = 0
    while running:
        j += 1
        loops = [build_loop(pass_experiment(experiments[i], j)) for i in running]
        for i, loop in zip(running, loops):
            if tables[i] is not None:
                loop.controller.table = tables[i]
        results, _, failures = simulate_loops(loops)
        still = []
        for i, loop, result, failure in zip(running, loops, results, failures):
            diverged = None if result is None else first_divergence(     # where and why a run alone would stop
                result.time, result.position, result.reference_position,
                path_bound(loop.curve, loop.schedule, loop.divergence_factor))
            if result is None or diverged:
                out[i] = (loop, None, failure or diverged[1])
            elif j == passes(experiments[i]):
                out[i] = (loop, result, "")
            else:
                tables[i] = next_correction(experiments[i], result, tables[i])
                still.append(i)
        running = still
    return out


def pass_bag(bag: Path, j: int) -> Path:
    """Pass j's bag: ``<stem>_pass<j>.mcap`` beside ``bag``."""
    bag = Path(bag)
    return bag.with_name(f"{bag.stem}_pass{j}{bag.suffix or '.mcap'}")


def learned_path(bag) -> Path:
    """Where the correction a pass plays back is kept: ``<its bag's stem>_learned.npy`` beside its bag."""
    bag = Path(bag)
    return bag.with_name(f"{bag.stem}_learned.npy")


def _save(path, table) -> None:
    with open(path, "wb") as stream:
        np.save(stream, table)


def run_passes(config: Path, experiment: Experiment, bag: Path, run, progress=None) -> list:
    """Every pass through the node graph: ``run(path, bag, experiment)`` runs one (runner.run_graph with the
    caller's layout and domain) and returns its bag. Returns the passes' bags."""
    bags, table, last = [], None, passes(experiment)
    with tempfile.TemporaryDirectory(prefix="contouring_ros_pass_") as directory:
        for j in range(1, last + 1):
            target = pass_bag(bag, j)
            target.parent.mkdir(parents=True, exist_ok=True)
            path, this_pass = config, experiment
            specs = [f"{key}={value}" for key, value in pass_settings(experiment, j).items()]
            if table is not None:
                learned = learned_path(target).resolve()
                write_atomically(learned, lambda tmp: _save(tmp, table))
                specs.append(f"ccc.learned_file={learned}")
            if specs:
                specs.append(f'experiment.name="{experiment.name}"')   # each pass keeps the experiment's name
                folder = Path(directory) / f"pass{j}"
                folder.mkdir()
                path, this_pass = written_settings(config, specs, folder)
            bags.append(run(path, target, this_pass))
            recorded = read_run(bags[-1], parsed=this_pass)
            if progress is not None:
                progress(j, bags[-1], recorded)
            if j < last:
                table = next_correction(experiment, recorded.result, table)
    return bags
