"""Benchmark: control steps per wall-clock second of an experiment through the process graph.

Prints, for each of ``--runs`` runs of the experiment (default: the default experiment): the total wall
time from launch to exit, and the lockstep rate measured by the recorder between the first and the last
message of the run (start-up and shutdown excluded). Also prints the in-process simulation's rate, and
the ratio between the two in the same run.

Usage: python bench/graph_speed.py [CONFIG] [--runs N]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from contouring_ros.bag import RUN_METADATA, read_metadata  # noqa: E402
from contouring_ros.config import build_loop, load_experiment  # noqa: E402
from contouring_ros.core.simulation import simulate  # noqa: E402
from contouring_ros.runner import run_graph  # noqa: E402


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


def lockstep_run(config, bag: Path, layout: str) -> tuple[float, float]:
    """One run through the graph: (seconds from launch to exit, lockstep steps per second as the
    recorder measured them between the first and the last message)."""
    steps = load_experiment(config).n_steps
    start = time.perf_counter()
    run_graph(config, bag, layout=layout)
    total = time.perf_counter() - start
    return total, (steps - 1) / float(read_metadata(bag)[RUN_METADATA]["wall_seconds_first_to_last_message"])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("config", nargs="?", default=str(ROOT / "config" / "paper000_b_ismc_h50_newton.yaml"))
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--layout", choices=["process", "composed"], default="process")
    args = parser.parse_args()
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
