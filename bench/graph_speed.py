"""Benchmark: control steps per wall-clock second of the default experiment through the process graph.

Prints, in one run: the in-process simulation rate, the graph's total wall time (start-up included) and
its steady rate (steps between the first and last /clock message divided by the wall time between them,
taken from the recorder's receive order is not available, so the steady rate is measured as
(steps) / (wall time - start-up time of an empty run)).

Usage: python bench/graph_speed.py [config.yaml]
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from contouring_ros.config import build_loop, load_experiment  # noqa: E402
from contouring_ros.core.simulation import simulate  # noqa: E402
from contouring_ros.runner import run_graph  # noqa: E402


def shortened(path: Path, duration: float) -> str:
    return path.read_text().replace("    sample_time: 0.001\n", f"    sample_time: 0.001\n    duration: {duration}\n", 1)


def main():
    config = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "config" / "paper000_b_ismc_h50_newton.yaml"
    experiment = load_experiment(config)
    loop = build_loop(experiment)
    start = time.perf_counter()
    simulate(loop)
    sim = time.perf_counter() - start
    print(f"in-process simulation: {experiment.n_steps} steps in {sim:.3f} s = {experiment.n_steps / sim:.0f} steps/s "
          f"({experiment.n_steps * experiment.sample_time / sim:.1f}x real time)")
    with tempfile.TemporaryDirectory() as tmp:
        short = Path(tmp) / "short.yaml"
        short.write_text(shortened(config, 0.01))      # 11 steps: start-up and shutdown cost
        start = time.perf_counter()
        run_graph(short, Path(tmp) / "short.mcap")
        overhead = time.perf_counter() - start
        start = time.perf_counter()
        run_graph(config, Path(tmp) / "full.mcap")
        total = time.perf_counter() - start
    steps = experiment.n_steps - 11
    rate = steps / (total - overhead)
    print(f"process graph: {experiment.n_steps} steps in {total:.2f} s wall (start-up + shutdown {overhead:.2f} s)")
    print(f"process graph, lockstep: {rate:.0f} control steps per wall second "
          f"(real-time factor {rate * experiment.sample_time:.2f}); {1e6 / rate:.0f} us per step")


if __name__ == "__main__":
    main()
