"""What the benchmark's reference methods do at their tuned gains: each cross-coupled ILC row's error pass by
pass, and each MPCC row's solve time per step, on the scenario's realistic machine (the benchmark's nominal
run: no model mismatch, the machine's first noise seeds).

It reads the tuned gains of a benchmark CSV (``contouring-ros benchmark`` writes reports/benchmark.csv),
rebuilds each row's sections as the benchmark did (:func:`contouring_ros.studies.benchmark.plan`,
:func:`~contouring_ros.studies.machine.fit_to_machine`) and runs them in-process. ``--file-gains`` runs the rows'
file gains instead (for a scenario whose tuning found no admissible point).

Usage: python tools/reference_methods.py [reports/benchmark.csv] [--file-gains]
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from contouring_ros.studies.benchmark import plan, scenario_families  # noqa: E402
from contouring_ros.core.simulation import simulate  # noqa: E402
from contouring_ros.experiment.build import build_loop  # noqa: E402
from contouring_ros.studies.learning import simulate_passes  # noqa: E402
from contouring_ros.studies.sweep import score_one  # noqa: E402
from contouring_ros.studies.gains import sections_with_gains  # noqa: E402
from contouring_ros.studies.machine import fit_to_machine, machine_settings  # noqa: E402
from contouring_ros.studies.outcomes import experiment_for, run_outcomes  # noqa: E402


def _sections(family, row: dict, file_gains: bool) -> tuple:
    """(the row's experiment on the realistic machine, the machine) with its tuned (or file) gains."""
    combos, _ = plan(family)
    combo = next(c for c in combos if (c.estimator, c.controller, c.servo) ==
                 (row["estimator"], row["controller"], row["servo"]))
    data = family.data[family.proposed]
    ideal = run_outcomes(data, {}, [{}], family.from_time, family.name)[0]
    machine = machine_settings(data, "realistic", ideal.peak_command if ideal.ok else ())
    sections = fit_to_machine(data, combo.sections, machine)
    gains = json.loads(row["file_gains" if file_gains or not row["gains"] else "gains"] or "{}")
    sections = sections_with_gains(sections, gains)
    return experiment_for(data, sections, machine, family.name), gains


def ilc_passes(family, row: dict, file_gains: bool) -> None:
    experiment, gains = _sections(family, row, file_gains)
    print(f"\n{row['scenario']}: {row['estimator']} + ilc / {row['servo']}, gains {gains} "
          f"({'file' if file_gains or not row['gains'] else 'tuned'}), from t = {family.from_time:g} s")
    print(f"{'pass':>6} {'TACE [um]':>12} {'MCE [um]':>12}")
    for j, (loop, result) in enumerate(simulate_passes(experiment), 1):
        scores, failure = score_one(loop, result, family.from_time)
        print(f"{j:>6} {scores.tace * 1e6:>12.4g} {scores.mce * 1e6:>12.4g}" if scores else f"{j:>6} {failure}")


def mpcc_solve_times(family, row: dict, file_gains: bool) -> None:
    experiment, gains = _sections(family, row, file_gains)
    loop = build_loop(experiment)
    result = simulate(loop)
    times = np.asarray(loop.controller.solve_times) * 1e6
    scores, _ = score_one(loop, result, family.from_time)
    print(f"\n{row['scenario']}: {row['estimator']} + mpcc / {row['servo']}, gains {gains}, horizon "
          f"{experiment.controller['horizon']}, command_limit {experiment.controller['command_limit']}")
    print(f"solve time per step [us]: median {np.median(times):.0f}, mean {times.mean():.0f}, 99th percentile "
          f"{np.percentile(times, 99):.0f}, max {times.max():.0f} over {len(times)} steps; "
          f"{loop.controller.unconverged} solves ended at OSQP's iteration limit; "
          f"TACE {scores.tace * 1e6:.4g} um, MCE {scores.mce * 1e6:.4g} um")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("csv", nargs="?", default=str(ROOT / "reports" / "benchmark.csv"))
    parser.add_argument("--file-gains", action="store_true", help="the rows' file gains, not the tuned ones")
    args = parser.parse_args(argv)
    families = {f.name: f for f in scenario_families()}
    with open(args.csv, newline="") as stream:
        rows = [r for r in csv.DictReader(stream) if r["controller"] in ("ilc", "mpcc") and r["file_gains"]]
    for row in rows:
        family = families[row["scenario"]]
        (ilc_passes if row["controller"] == "ilc" else mpcc_solve_times)(family, row, args.file_gains)
    return 0


if __name__ == "__main__":
    sys.exit(main())
