"""Parameter sweeps: the in-process simulation over every combination of a grid.

Combinations of one structure (the same curve, schedule, plant, servo, estimator and controller classes)
run vectorised, up to ``BATCH`` at a time along a batch axis (:mod:`contouring_ros.core.batch`), where
every class has a batch path; the others run one by one. Batches and single runs share a process pool.

A grid key names a place in the experiment file: ``<node section>.<key>[.<subkey>]`` for a node's
parameter (``ccc.kp``, ``x/servo.a``, ``contour_estimator.k_prime``) or ``<key>[.<subkey>]`` for a shared
one (``curve.h``, ``schedule.duration``). Every combination is validated like a file before it runs.
"""
from __future__ import annotations

import copy
import csv
import itertools
import math
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass


from .config import GLOBAL_SECTION, ROS_PARAMETERS, build_loop, experiment_from_data, read_yaml
from .core.batch import batch_problem, simulate_batch, structure
from .core.simulation import simulate
from .errors import ConfigError
from .scoring import score_run

__all__ = ["parse_grid", "combinations", "SweepRow", "run_sweep", "format_sweep", "write_sweep_csv"]


def parse_grid(specs: list) -> dict:
    """['ccc.kp=0.5,1,2', 'curve.h=50,100'] -> {'ccc.kp': [0.5, 1, 2], 'curve.h': [50, 100]}."""
    grid = {}
    for spec in specs:
        key, sep, values = spec.partition("=")
        if not sep or not key or not values:
            raise ConfigError(f"--grid {spec}: expected key=value1,value2,...")
        grid[key] = [read_yaml(value, f"--grid {key}") for value in values.split(",")]
    return grid


def _set(data: dict, key: str, value):
    section, _, rest = key.partition(".")
    node = f"/{section}"
    if node in data and rest:
        target, path = data[node][ROS_PARAMETERS], rest.split(".")
    else:
        target, path = data[GLOBAL_SECTION][ROS_PARAMETERS], key.split(".")
    for part in path[:-1]:
        target = target.setdefault(part, {})
        if not isinstance(target, dict):
            raise ConfigError(f"--grid {key}: {part} is not a mapping")
    target[path[-1]] = value


def combinations(text: str, grid: dict) -> list:
    """(settings, validated experiment) for every combination of the grid's values.

    The file is read once; each combination is a copy of its data with the grid's values set, validated
    like a file (an invalid one is refused naming its settings) without another YAML round trip.
    """
    base = read_yaml(text, "sweep")
    out = []
    for values in itertools.product(*grid.values()):
        data = copy.deepcopy(base)
        settings = dict(zip(grid, values))
        for key, value in settings.items():
            _set(data, key, value)
        try:
            out.append((settings, experiment_from_data(data, "sweep combination")))
        except ConfigError as error:
            raise ConfigError(f"--grid {settings}: {error}") from None
    return out


BATCH = 250      # combinations per vectorised batch (memory: about 0.25 MB per combination and 1000 steps)


@dataclass(frozen=True)
class SweepRow:
    settings: dict
    scores: object
    alone: str = ""            # why it ran one by one ("" when it ran in a vectorised batch)

    @property
    def vectorised(self) -> bool:
        return not self.alone


def _score_chunk(experiments: list) -> tuple:
    """Scores of each experiment, and why each ran alone ("" for those in a vectorised batch, one batch per
    structure)."""
    loops = [build_loop(e) for e in experiments]
    results, alone, groups = [None] * len(loops), [""] * len(loops), {}
    for i, loop in enumerate(loops):
        groups.setdefault(structure(loop), []).append(i)
    for group in groups.values():
        members = [loops[i] for i in group]
        why = batch_problem(members if len(members) > 1 else members * 2) \
            or ("" if len(members) > 1 else "too few combinations of one structure to batch")
        batch = simulate_batch(members) if not why else None
        for j, i in enumerate(group):
            results[i], alone[i] = (batch[j], "") if batch else (simulate(loops[i]), why)
    return [score_run(loop.curve, result) for loop, result in zip(loops, results)], alone


def _shape(section):
    """A section's settings with every number blanked: experiments whose shapes are equal differ only in
    numbers, and so (almost always) build loops of one structure."""
    if isinstance(section, dict):
        return tuple((key, _shape(value)) for key, value in section.items())
    if isinstance(section, (list, tuple)):
        return tuple(_shape(value) for value in section)
    return None if isinstance(section, (int, float)) and not isinstance(section, bool) else section


def _chunks(experiments: list, workers: int, batch: int) -> list:
    """Indices of the experiments in chunks of one shape and step count each, at most ``batch`` long,
    spread so that every worker gets some. (Numbers can still change a loop's structure, say a branch
    check of 0 samples beside one of 256: the worker batches each structure of its chunk apart.)"""
    groups = {}
    for index, e in enumerate(experiments):
        key = (e.n_steps, e.sample_time, e.axes, _shape([e.curve, e.schedule, e.initial_state, e.plants, e.servos,
                                                          e.estimator, e.controller]))
        groups.setdefault(key, []).append(index)
    size = max(1, min(batch, math.ceil(len(experiments) / (2 * workers))))
    return [group[i:i + size] for group in groups.values() for i in range(0, len(group), size)]


def run_sweep(text: str, grid: dict, workers: int | None = None, progress: bool = False, batch: int = BATCH) -> list:
    """Score every combination (validated first), ranked by MCE then TACE; at most ``batch`` combinations
    per vectorised batch (1: each alone)."""
    from tqdm import tqdm
    combos = combinations(text, grid)
    experiments = [experiment for _, experiment in combos]
    workers = workers or os.cpu_count() or 1
    chunks = _chunks(experiments, workers, batch)
    scores, alone = [None] * len(combos), [""] * len(combos)
    with ProcessPoolExecutor(max_workers=workers) as pool, \
            tqdm(total=len(combos), desc="sweep", disable=not progress) as bar:
        for chunk, (chunk_scores, batched) in zip(chunks, pool.map(_score_chunk, [[experiments[i] for i in chunk]
                                                                                   for chunk in chunks])):
            for i, s, why in zip(chunk, chunk_scores, batched):
                scores[i], alone[i] = s, why
            bar.update(len(chunk))
    rows = [SweepRow(settings, s, why) for (settings, _), s, why in zip(combos, scores, alone)]
    return sorted(rows, key=lambda row: (row.scores.mce, row.scores.tace))


def format_sweep(rows: list, limit: int = 20) -> str:
    keys = list(rows[0].settings) if rows else []
    head = ["rank"] + keys + ["MCE [um]", "TACE [um]", "RMS [um]"]
    lines = ["  ".join(f"{h:>12}" for h in head)]
    for rank, row in enumerate(rows[:limit], 1):
        cells = [str(rank)] + [str(row.settings[k]) for k in keys] + \
            [f"{row.scores.mce * 1e6:.4g}", f"{row.scores.tace * 1e6:.4g}", f"{row.scores.rms * 1e6:.4g}"]
        lines.append("  ".join(f"{c:>12}" for c in cells))
    if len(rows) > limit:
        lines.append(f"... {len(rows) - limit} more in the CSV")
    return "\n".join(lines)


def write_sweep_csv(rows: list, path) -> None:
    keys = list(rows[0].settings) if rows else []
    with open(path, "w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(["rank"] + keys + ["mce_m", "tace_m", "rms_m", "estimation_max_m"])
        for rank, row in enumerate(rows, 1):
            writer.writerow([rank] + [row.settings[k] for k in keys]
                            + [row.scores.mce, row.scores.tace, row.scores.rms, row.scores.estimation_max])
