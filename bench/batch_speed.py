"""Benchmark: configuration-steps per second of the in-process simulation, vectorised and one by one, per class.

For each class with a batch path listed below, a scenario of config/ that uses it (the spline and the random
disturbance: the default experiment with its curve or an axis' disturbance replaced, as no scenario file uses
them) is cut to ``--seconds`` of simulated time and ``--batch`` configurations of it (one setting spread over
a range) are simulated:

- vectorised: all of them in one batch (:func:`contouring_ros.core.batch.simulate_batch`);
- one by one: ``--alone`` of them, each with :func:`contouring_ros.core.simulation.simulate` (what a sweep
  did for these classes before they had a batch path, and still does for a class without one).

It prints configuration-steps per second of wall time and of process CPU time (the machine may be shared:
CPU time is the steadier figure), each the median of ``--repeat`` measurements, the two sides alternated,
and the ratio vectorised / one by one. One process, one core: a sweep multiplies either figure by its
workers.

Usage: python bench/batch_speed.py [--batch 64] [--alone 4] [--seconds 0.5] [--repeat 3] [--only LABEL ...]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from contouring_ros.config import build_loop  # noqa: E402
from contouring_ros.core.batch import batch_problem, simulate_batch  # noqa: E402
from contouring_ros.core.simulation import simulate  # noqa: E402
from contouring_ros.sweep import combinations  # noqa: E402

CONFIG = ROOT / "config"
DEFAULT = CONFIG / "paper000_b_ismc_h50_newton.yaml"


def _cut(path: Path, seconds: float) -> dict:
    data = yaml.safe_load(path.read_text())
    data["/**"]["ros__parameters"]["duration"] = seconds
    return data


def _file(name: str):
    return lambda seconds: yaml.safe_dump(_cut(CONFIG / name, seconds))


def _spline(seconds: float) -> str:
    data = _cut(DEFAULT, seconds)
    x = np.linspace(-0.02, 0.02, 9)
    data["/**"]["ros__parameters"]["curve"] = {"type": "spline", "x": x.tolist(), "y": (50.0 * x * x).tolist()}
    data["/**"]["ros__parameters"]["schedule"] = {"type": "feedrate", "feedrate": 0.02, "acceleration": 0.5}
    return yaml.safe_dump(data)


def _random(seconds: float) -> str:
    data = _cut(DEFAULT, seconds)
    data["/x/plant"]["ros__parameters"]["disturbance"] = {"type": "random", "std": 1e-4, "seed": 1}
    return yaml.safe_dump(data)


# label, the classes it times, the experiment (a function of the simulated seconds), the setting spread, its range
CASES = [
    ("natural-local", "NaturalLocalEstimator + TaskFramePD (2 axes)", _file("paper003_ellipse_natural_local_fn80.yaml"),
     "ccc.f_n", (60.0, 100.0)),
    ("task-frame-3d", "TaskFramePD first order + tangent line (3 axes)", _file("paper003_helix_first_order_f15_10.yaml"),
     "ccc.f_n", (12.0, 18.0)),
    ("foot-point-tvt", "FootPointSearchEstimator + TangentialVelocityCCC", _file("paper002_butterfly_c3_tvt.yaml"),
     "ccc.kc", (100.0, 180.0)),
    ("foot-point-ccc", "FootPointSearchEstimator + VariableGainCCC", _file("paper002_butterfly_c4_foot_point_ccc.yaml"),
     "ccc.kp", (100.0, 180.0)),
    ("adaptive-tnb", "AdaptiveTNBCCC (+ osculating circle)", _file("paper001_caseII_adaptive_tnb.yaml"),
     "ccc.alpha", (30.0, 50.0)),
    ("gcode", "ToolPath + FeedPlan (+ Newton, unit vector)", _file("gcode_example_part.yaml"), "ccc.kp", (0.5, 2.0)),
    ("spline", "SplineCurve + FeedrateSchedule (default experiment's loop)", _spline, "ccc.kp", (0.5, 4.0)),
    ("random", "RandomDisturbance (default experiment's loop)", _random, "x/plant.disturbance.seed", None),
    ("default", "reference: the default experiment (ISMC, Newton, unit vector)", _file(DEFAULT.name), "ccc.kp",
     (0.5, 4.0)),
]


def _loops(text: str, key: str, span, count: int) -> list:
    values = list(range(1, count + 1)) if span is None else np.linspace(*span, count).tolist()
    return [build_loop(experiment) for _, experiment in combinations(text, {key: values})]


def _timed(run) -> tuple[float, float]:
    wall, cpu = time.perf_counter(), time.process_time()
    run()
    return time.perf_counter() - wall, time.process_time() - cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=64, help="configurations simulated as one batch")
    parser.add_argument("--alone", type=int, default=4, help="configurations simulated one by one")
    parser.add_argument("--seconds", type=float, default=0.5, help="simulated seconds per configuration")
    parser.add_argument("--repeat", type=int, default=3, help="measurements of each side (medians printed)")
    parser.add_argument("--only", nargs="*", help="labels of the cases to run (default: all)")
    args = parser.parse_args()
    print(f"configuration-steps/s, {args.seconds:g} s of each experiment; vectorised: one batch of {args.batch}; "
          f"one by one: {args.alone} runs; wall (CPU), medians of {args.repeat}")
    print(f"{'case':16} {'vectorised':>22} {'one by one':>20} {'ratio':>12}  classes")
    for label, classes, experiment, key, span in CASES:
        if args.only and label not in args.only:
            continue
        text = experiment(args.seconds)
        batch = _loops(text, key, span, args.batch)
        problem = batch_problem(batch)
        if problem:
            print(f"{label:16} not batchable: {problem}")
            continue
        steps = batch[0].n_steps
        vectorised, alone = [], []
        for _ in range(args.repeat):        # simulate_batch leaves its loops untouched; simulate needs fresh ones
            vectorised.append(_timed(lambda: simulate_batch(batch)))
            loops = _loops(text, key, span, args.alone)
            alone.append(_timed(lambda: [simulate(loop) for loop in loops]))
        vec = tuple(args.batch * steps / statistics.median(t[i] for t in vectorised) for i in (0, 1))
        one = tuple(args.alone * steps / statistics.median(t[i] for t in alone) for i in (0, 1))
        print(f"{label:16} {vec[0]:>10.0f} ({vec[1]:>9.0f}) {one[0]:>9.0f} ({one[1]:>8.0f}) "
              f"{vec[0] / one[0]:>5.1f} ({vec[1] / one[1]:>4.1f})  {classes}", flush=True)


if __name__ == "__main__":
    main()
