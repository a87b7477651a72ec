"""Benchmark: configuration-steps per second of the in-process simulation, vectorised and one by one, per class.

For each class with a batch path listed below, a scenario of config/ that uses it (the spline and the random
disturbance: the default experiment with its curve or an axis' disturbance replaced, as no scenario file uses
them) is cut to ``--seconds`` of simulated time and ``--batch`` configurations of it (one setting spread over
a range) are simulated:

- vectorised: all of them in one batch (:func:`contouring_ros.core.batch.simulate_batch`);
- one by one: ``--alone`` of them, each with :func:`contouring_ros.core.simulation.simulate` (what a sweep
  did for these classes before they had a batch path, and still does for a class without one).

It prints configuration-steps per second of wall time and of process CPU time (the machine may be shared:
CPU time is the steadier figure), each the median of ``--repeat`` measurements, the sides alternated, and
the ratio vectorised / one by one. One process, one core: a sweep multiplies either figure by its workers.

Where numba is installed (:mod:`contouring_ros.core.kernels`) each case is measured with the compiled
kernels and with the pure numpy path (``pure`` lines), alternated in the same process, and the speed-up is
printed; ``--pure`` measures the pure path alone.

``--mixed SCENARIO`` times the rows of one benchmark scenario as a tuning's round runs them: ``--batch`` members of
each of its combinations on its realistic machine, all in mixed batches (``simulate_loops(mixed=True)``: each
part stacked per class) against a batch per combination (``simulate_loops``), the sides alternated.

``--sweep W ...`` then times :func:`contouring_ros.studies.sweep.run_sweep` of the default experiment (``--sweep-size``
combinations of ccc.kp, ``--seconds`` each) with each number of local worker processes W, and prints
configuration-steps per second of wall time and the scaling relative to the first W.

Usage: python bench/batch_speed.py [--batch 64] [--alone 4] [--seconds 0.5] [--repeat 3] [--only LABEL ...]
       [--pure] [--sweep 1 2] [--sweep-size 64] [--mixed SCENARIO]
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

from contouring_ros.experiment.build import build_loop  # noqa: E402
from contouring_ros.core import kernels  # noqa: E402
from contouring_ros.core.batch import batch_problem, simulate_batch  # noqa: E402
from contouring_ros.core.curves import Parabola  # noqa: E402
from contouring_ros.core.simulation import simulate  # noqa: E402
from contouring_ros.studies.sweep import combinations, run_sweep  # noqa: E402

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
    ("mpcc", "ModelPredictiveContouring (every member's QP a row of one solve)", _file("mpcc_ellipse.yaml"),
     "ccc.q_contour", (3e5, 3e6)),
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


def _case(label, classes, text, key, span, args, modes) -> None:
    batch = _loops(text, key, span, args.batch)
    problem = batch_problem(batch)
    if problem:
        print(f"{label:16} not batchable: {problem}")
        return
    steps = batch[0].n_steps
    timings = {mode: ([], []) for mode in modes}
    for _ in range(args.repeat):        # simulate_batch leaves its loops untouched; simulate needs fresh ones
        for mode in modes:
            kernels.ENABLED = mode == "compiled"
            vectorised, alone = timings[mode]
            vectorised.append(_timed(lambda: simulate_batch(batch)))
            loops = _loops(text, key, span, args.alone)
            alone.append(_timed(lambda: [simulate(loop) for loop in loops]))
    kernels.ENABLED = COMPILED
    rates = {}
    for mode in modes:
        vectorised, alone = timings[mode]
        vec = tuple(args.batch * steps / statistics.median(t[i] for t in vectorised) for i in (0, 1))
        one = tuple(args.alone * steps / statistics.median(t[i] for t in alone) for i in (0, 1))
        rates[mode] = vec, one
        name = label if mode == modes[0] else f"  {mode}"
        print(f"{name:16} {vec[0]:>10.0f} ({vec[1]:>9.0f}) {one[0]:>9.0f} ({one[1]:>8.0f}) "
              f"{vec[0] / one[0]:>5.1f} ({vec[1] / one[1]:>4.1f})  {classes if mode == modes[0] else ''}", flush=True)
    if len(modes) == 2:
        (vc, oc), (vp, op) = rates["compiled"], rates["pure"]
        print(f"{'  speed-up':16} {vc[0] / vp[0]:>10.2f} ({vc[1] / vp[1]:>9.2f}) {oc[0] / op[0]:>9.2f} "
              f"({oc[1] / op[1]:>8.2f})        compiled / pure", flush=True)


def _sweeps(args) -> None:
    text = _file(DEFAULT.name)(args.seconds)
    values = np.linspace(0.5, 4.0, args.sweep_size).tolist()
    steps = build_loop(combinations(text, {"ccc.kp": values[:1]})[0][1]).n_steps
    print(f"\nsweep of the default experiment: {args.sweep_size} combinations of ccc.kp, {args.seconds:g} s each "
          f"(run_sweep, local processes; configuration-steps/s of wall time, medians of {args.repeat})")
    first = None
    for workers in args.sweep:
        walls = []
        for _ in range(args.repeat):
            wall = time.perf_counter()
            run_sweep(text, {"ccc.kp": values}, workers=workers)
            walls.append(time.perf_counter() - wall)
        rate = args.sweep_size * steps / statistics.median(walls)
        first = first or rate
        print(f"  {workers} worker{'s' if workers > 1 else ' '} {rate:>10.0f}   x{rate / first:.2f}", flush=True)


def _mixed(args) -> None:
    from contouring_ros.studies.benchmark import plan, reference_job, scenario_families, select_families
    from contouring_ros.studies.machine import fit_to_machine
    from contouring_ros.studies.outcomes import experiment_for
    from contouring_ros.studies.sweep import simulate_loops
    family = select_families(scenario_families(), [args.mixed])[0]
    data = family.data[family.proposed]
    machine = dict(reference_job(data, family.from_time, family.name).machine, duration=args.seconds)
    combos = [c for c in plan(family)[0] if c.gain_keys]
    rng = np.random.default_rng(1)

    def loops():      # each combination's file gains, each gain x U(0.5, 2) per member
        out = []
        for combo in combos:
            sections = fit_to_machine(data, combo.sections, machine)
            for _ in range(args.batch):
                ccc = dict(sections["/ccc"], **{k: sections["/ccc"][k] * rng.uniform(0.5, 2.0) for k in combo.gain_keys
                                               if isinstance(sections["/ccc"].get(k), (int, float))})
                try:
                    out.append(build_loop(experiment_for(data, {**sections, "/ccc": ccc}, machine, "bench")))
                except Exception:       # noqa: BLE001 - a drawn gain a pairing refuses: left out
                    pass
        return out
    rates, members = {"mixed": [], "by structure": []}, []
    with np.errstate(all="ignore"):
        for _ in range(args.repeat):
            for mode in rates:
                batch = loops()         # a drawn gain a pairing refuses leaves a member out: each batch counted
                steps = sum(loop.n_steps for loop in batch)
                rates[mode].append([steps / t for t in _timed(lambda: simulate_loops(batch, mixed=mode == "mixed"))])
                members.append(len(batch))
    print(f"\n{family.name}: {len(combos)} combinations x {args.batch} members ({min(members)}-{max(members)} runs), "
          f"{args.seconds:g} s each, as a tuning's round (configuration-steps/s, wall (CPU), medians of {args.repeat})")
    rates = {mode: tuple(statistics.median(r[i] for r in runs) for i in (0, 1)) for mode, runs in rates.items()}
    for mode, (wall, cpu) in rates.items():
        print(f"  {mode:13} {wall:>10.0f} ({cpu:>9.0f})", flush=True)
    print(f"  {'ratio':13} {rates['mixed'][0] / rates['by structure'][0]:>10.2f} "
          f"({rates['mixed'][1] / rates['by structure'][1]:>9.2f})", flush=True)


COMPILED = kernels.ENABLED


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=64, help="configurations simulated as one batch")
    parser.add_argument("--alone", type=int, default=4, help="configurations simulated one by one")
    parser.add_argument("--seconds", type=float, default=0.5, help="simulated seconds per configuration")
    parser.add_argument("--repeat", type=int, default=3, help="measurements of each side (medians printed)")
    parser.add_argument("--only", nargs="*", help="labels of the cases to run (default: all)")
    parser.add_argument("--pure", action="store_true", help="the pure numpy path only (no compiled kernels)")
    parser.add_argument("--sweep", type=int, nargs="*", default=[], metavar="W",
                        help="also time a sweep of the default experiment with each number of workers")
    parser.add_argument("--sweep-size", type=int, default=64, help="combinations of that sweep")
    parser.add_argument("--mixed", metavar="SCENARIO",
                        help="time a benchmark scenario's rows as mixed batches against a batch per combination")
    args = parser.parse_args()
    modes = ["compiled", "pure"] if COMPILED and not args.pure else ["pure"]
    if COMPILED:                    # compile the kernels of the Newton cases' curve before anything is timed
        kernels.COMPILE_AFTER = 0   # (a process compiles after its first pure steps; here, from the first)
        parabola = Parabola(0.02, 50.0)
        kernels.newton_flow(parabola)(np.zeros(2), 0.0, 0.0, 0.9, 0.1, 0.5, 1e-18, 200)
        kernels.newton_flow_batch(parabola, np.zeros((2, 2)), 0.0, 0.0, 0.9, 0.1, 0.5, 1e-18, 200,
                                  np.ones((2, 1), dtype=bool))
    if args.mixed:
        _mixed(args)
        return
    print(f"configuration-steps/s, {args.seconds:g} s of each experiment; vectorised: one batch of {args.batch}; "
          f"one by one: {args.alone} runs; wall (CPU), medians of {args.repeat}; "
          + ("compiled kernels (numba) and the pure numpy path alternated" if len(modes) == 2 else
             "the pure numpy path" + ("" if COMPILED else " (numba is not installed)")))
    print(f"{'case':16} {'vectorised':>22} {'one by one':>20} {'ratio':>12}  classes")
    for label, classes, experiment, key, span in CASES:
        if args.only and label not in args.only:
            continue
        _case(label, classes, experiment(args.seconds), key, span, args, modes)
    if args.sweep:
        _sweeps(args)


if __name__ == "__main__":
    main()
