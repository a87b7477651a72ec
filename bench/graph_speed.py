"""Benchmark: control steps per wall-clock second of an experiment through the node graph.

Prints, for each of ``--runs`` runs of the experiment (default: the default experiment): the total wall
time from launch to exit, and the lockstep rate measured by the recorder between the first and the last
message of the run (start-up and shutdown excluded). Also prints the in-process simulation's rate, and
the ratio between the two in the same run.

Usage: python bench/graph_speed.py [CONFIG | --axes N] [--runs N] [--layout process|composed|grouped|grouped-lean]
(``--axes N``: an N-axis straight line, 2 to 8 axes, built from config/line3d_newton_ismc.yaml)
"""
from __future__ import annotations

import argparse
import copy
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from contouring_ros.wire import graph  # noqa: E402
from contouring_ros.records.bag_reader import read_metadata  # noqa: E402
from contouring_ros.records.bag_writer import RUN_METADATA  # noqa: E402
from contouring_ros.experiment.build import build_loop  # noqa: E402
from contouring_ros.experiment.files import load_experiment  # noqa: E402
from contouring_ros.core.simulation import simulate  # noqa: E402
from contouring_ros.run.runner import run_graph  # noqa: E402


def simulation_rate(config, runs: int = 5) -> tuple[float, float]:
    """The in-process simulation of ``config``, median of ``runs`` runs: (steps per second, real-time factor)."""
    experiment = load_experiment(config)
    rates = []
    for _ in range(runs):
        loop = build_loop(experiment)
        start = time.perf_counter()
        simulate(loop)
        rates.append(experiment.n_steps / (time.perf_counter() - start))
    rate = statistics.median(rates)
    return rate, rate * experiment.sample_time


AXIS_NAMES = ("x", "y", "z", "a", "b", "c", "u", "v")
LINE_TEMPLATE = ROOT / "config" / "line3d_newton_ismc.yaml"


def line_experiment(n_axes: int, duration: float) -> str:
    """An ``n_axes``-axis straight line (up to 8 axes: x y z a b c u v) cut to ``duration`` s: the 3-axis
    line3d_newton_ismc.yaml with every added axis a copy of its z axis (drive, servo)."""
    import yaml
    data = yaml.safe_load(LINE_TEMPLATE.read_text())
    axes = list(AXIS_NAMES[:n_axes])
    shared = data["/**"]["ros__parameters"]
    end = [0.3, 0.2, 0.1, 0.25, 0.15, 0.05, 0.12, 0.08][:n_axes]
    shared.update(axes=axes, duration=duration, curve={"type": "line", "start": [0.0] * n_axes, "end": end})
    shared["schedule"]["theta_end"] = float(sum(v * v for v in end) ** 0.5)
    shared["experiment"]["name"] = f"line{n_axes}d_newton_ismc"
    for role in ("plant", "servo"):
        template = data[f"/z/{role}"]
        for axis in ("x", "y", "z"):
            data.pop(f"/{axis}/{role}")
        for axis in axes:
            data[f"/{axis}/{role}"] = copy.deepcopy(LINE_SECTIONS[role].get(axis, template))
    class Quoted(yaml.SafeDumper):
        """Every string quoted (ROS 2 reads a bare y as true)."""

    Quoted.add_representer(str, lambda dumper, text: dumper.represent_scalar("tag:yaml.org,2002:str", text, style="'"))
    return yaml.dump(data, Dumper=Quoted, sort_keys=False)


def _line_sections() -> dict:
    import yaml
    data = yaml.safe_load(LINE_TEMPLATE.read_text())
    return {role: {axis: data[f"/{axis}/{role}"] for axis in ("x", "y", "z")} for role in ("plant", "servo")}


LINE_SECTIONS = _line_sections()


def layout_groups(layout: str, axes) -> list | None:
    """The groups of a named layout: ``process`` and ``composed`` have none (run_graph's own layouts);
    ``grouped`` puts each axis' plant and servo in one process and the interpolator, estimator and CCC in
    another (the recorder alone); ``grouped-lean`` puts every node but the recorder in one process and
    the recorder (bag writer, compression thread) in its own."""
    if layout == "grouped":
        return [f"{a}/plant,{a}/servo" for a in axes] + ["interpolator,contour_estimator,ccc"]
    if layout == "grouped-lean":
        return [",".join(n for n in graph.node_names(axes) if n != "/recorder")]
    return None


LAYOUTS = ("process", "composed", "grouped", "grouped-lean")


def run_layout(config, bag: Path, layout: str) -> Path:
    """run_graph with one of the layouts ``process``, ``composed``, ``grouped``, ``grouped-lean``."""
    groups = layout_groups(layout, load_experiment(config).axes)
    return run_graph(config, bag, layout="composed" if layout == "composed" else "process", groups=groups)


def lockstep_run(config, bag: Path, layout: str) -> tuple[float, float]:
    """One run through the graph: (seconds from launch to exit, lockstep steps per second as the
    recorder measured them between the first and the last message)."""
    steps = load_experiment(config).n_steps
    start = time.perf_counter()
    run_layout(config, bag, layout)
    total = time.perf_counter() - start
    return total, (steps - 1) / float(read_metadata(bag)[RUN_METADATA]["wall_seconds_first_to_last_message"])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("config", nargs="?", default=str(ROOT / "config" / "paper000_b_ismc_h50_newton.yaml"))
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--layout", choices=LAYOUTS, default="process")
    parser.add_argument("--axes", type=int, help="instead of CONFIG: an N-axis line (2-8 axes, 2 s)")
    args = parser.parse_args()
    if args.axes:
        args.config = Path(tempfile.mkdtemp()) / f"line{args.axes}d.yaml"
        args.config.write_text(line_experiment(args.axes, 2.0))
    experiment = load_experiment(args.config)
    steps = experiment.n_steps
    sim_rate, factor = simulation_rate(args.config)
    print(f"in-process simulation: {sim_rate:.0f} steps/s ({factor:.1f}x real time)")
    totals, rates = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.runs):
            total, rate = lockstep_run(args.config, Path(tmp) / f"run{i}.mcap", args.layout)
            totals.append(total)
            rates.append(rate)
            print(f"run {i + 1}: {steps} steps, {total:.2f} s launch to exit ({steps / total:.0f} steps/s "
                  f"overall), lockstep {(steps - 1) / rate:.2f} s = {rate:.0f} steps/s ({1e6 / rate:.0f} us/step)")
    rate = statistics.median(rates)
    print(f"{args.layout} graph, lockstep, median of {args.runs}: {rate:.0f} control steps per wall second "
          f"(real-time factor {rate * experiment.sample_time:.2f}); overall incl. start-up "
          f"{steps / statistics.median(totals):.0f} steps/s")
    print(f"ratio in-process / graph lockstep: {sim_rate / rate:.1f}")


if __name__ == "__main__":
    main()
