"""Benchmark: the MPCC controller's solve time per step (core/mpc.py), and what its command limit costs.

Paper 003's ellipse (the ``fn100`` file: its plants, direct servos and 10 V drives) with the paper's task-frame
PD replaced by ``type: mpcc`` (horizon 20, q_contour 1e6, q_lag 1e4, r_rate 1e-6, disturbance_gain 0.2), run
in-process three ways: without a command limit (the QP's unconstrained optimum: one linear solve a step), with
the drives' 10 V (never reached on this path: the same linear solve, within the limit) and with 8 V (reached:
OSQP solves the steps whose optimum leaves the limit). For each it
prints the wall time of the solves (mean, median, 99th percentile, max: the machine may be shared, so the
median is the steadier figure), the run's CPU time, and the scores (MCE, TACE of the whole run; RMS exact
contour error from ``--from`` s), then the paper's task-frame PD's scores on the same file.

Usage: python bench/mpcc_solve_time.py [--horizon N] [--from T]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from contouring_ros.core.simulation import simulate  # noqa: E402
from contouring_ros.experiment.build import build_loop  # noqa: E402
from contouring_ros.experiment.validate import parse_experiment  # noqa: E402
from contouring_ros.records.scoring import score_run  # noqa: E402

SCENARIO = ROOT / "config" / "paper003_ellipse_natural_local_fn100.yaml"
MPCC = ("/ccc:\n  ros__parameters:\n    type: mpcc\n    mass: [1.0, 1.0]\n    damping: [798.5, 862.75]\n"
        "    gain: [16.23, 17.58]\n    horizon: {horizon}\n    q_contour: 1.0e6\n    q_lag: 1.0e4\n"
        "    r_rate: 1.0e-6\n    disturbance_gain: 0.2\n")


def _scores(loop, result, from_time) -> str:
    whole, steady = score_run(loop.curve, result), score_run(loop.curve, result, from_time)
    return (f"MCE {whole.mce * 1e6:.3f} um, TACE {whole.tace * 1e6:.4f} um, RMS from {from_time:g} s "
            f"{steady.rms * 1e6:.3f} um")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--horizon", type=int, default=20)
    parser.add_argument("--from", dest="from_time", type=float, default=0.3)
    args = parser.parse_args(argv)
    text = SCENARIO.read_text()
    head = text[:text.index("/ccc:")]
    for label, limit in (("no limit", ""), ("10 V limit (not reached)", "    command_limit: [10.0]\n"),
                         ("8 V limit (reached: OSQP where it binds)", "    command_limit: [8.0]\n")):
        loop = build_loop(parse_experiment(head + MPCC.format(horizon=args.horizon) + limit, "mpcc.yaml"))
        started = time.process_time()
        result = simulate(loop)
        cpu = time.process_time() - started
        solves = np.array(loop.controller.solve_times) * 1e6
        print(f"mpcc, {label}: solve [us] mean {solves.mean():.0f}, median {np.median(solves):.0f}, "
              f"p99 {np.percentile(solves, 99):.0f}, max {solves.max():.0f}; {loop.n_steps} steps in {cpu:.1f} s CPU; "
              + _scores(loop, result, args.from_time) + f"; largest command {np.abs(result.command).max():.3f}")
    loop = build_loop(parse_experiment(text, str(SCENARIO)))
    print("task_frame_pd (the paper's): " + _scores(loop, simulate(loop), args.from_time))
    return 0


if __name__ == "__main__":
    sys.exit(main())
