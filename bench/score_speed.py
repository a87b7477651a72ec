"""Benchmark: seconds and peak memory to score a long bag (default: 60 s, 3 axes, 1 kHz).

The bag is recorded from the in-process simulation with the recorder's layout (bag_writer.write_simulation),
then scored in a fresh process so that its peak resident memory is the scoring's own.

Usage: python bench/score_speed.py [CONFIG]
"""
from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

SCORE = """
import resource, sys, time
start = time.perf_counter()
from contouring_ros.records.scoring import score_bag
scores, run = score_bag(sys.argv[1])
elapsed = time.perf_counter() - start
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(f"{run.complete_steps} {elapsed:.3f} {peak:.1f} {scores.mce * 1e6:.4f}")
"""


def main():
    from contouring_ros.records.bag_writer import write_simulation
    from contouring_ros.experiment.build import build_loop
    from contouring_ros.experiment.files import load_experiment
    from contouring_ros.core.simulation import simulate
    config = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "config" / "line3d_newton_ismc.yaml"
    experiment = load_experiment(config)
    start = time.perf_counter()
    result = simulate(build_loop(experiment))
    print(f"simulated {experiment.n_steps} steps, {len(experiment.axes)} axes in {time.perf_counter() - start:.1f} s")
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / "long.mcap"
        start = time.perf_counter()
        write_simulation(bag, experiment, result)
        print(f"wrote {bag.stat().st_size / 1e6:.1f} MB in {time.perf_counter() - start:.1f} s")
        baseline = subprocess.run([sys.executable, "-c", "import resource, numpy, scipy.spatial, mcap; "
                                   "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)"],
                                  capture_output=True, text=True, cwd=ROOT).stdout.strip()
        out = subprocess.run([sys.executable, "-c", SCORE, str(bag)], capture_output=True, text=True, cwd=ROOT)
        if out.returncode:
            raise SystemExit(out.stderr)
        steps, seconds, peak, mce = out.stdout.split()
    print(f"scored {steps} steps in {float(seconds):.2f} s; peak resident memory {float(peak):.0f} MB "
          f"(imports alone {float(baseline):.0f} MB); MCE {mce} um")


if __name__ == "__main__":
    main()
