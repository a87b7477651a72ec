"""Compare two benchmark CSVs row by row: do the figures and verdicts survive a change of protocol?

A benchmark's verdicts are only worth as much as its tuning: if halving the optimiser's budget (or the
draws, or any other protocol number) moves the tuned errors and flips verdicts, the search had not
converged; if they stay, the smaller protocol gives the same answers for less time. Reads the
``benchmark.csv`` of a reference run (A) and of another run (B) of the same scenarios, pairs the rows by
scenario and combination, and prints

- how many rows are tuned in both, and where the status changed (robust, not robust, no admissible point);
- the ratio B / A of each tuned row's median TACE over the draws: its median and quartiles, and how many
  rows lie within 10% and 25% of A and beyond 2x (B better or worse);
- the TACE verdict against the proposed method (lower, higher, undecided): how many agree, and each that
  changed with both intervals;
- per scenario, the best other combination (lowest larger median ratio of MCE and TACE to the proposed
  method, as the report chooses it) in A and in B.

    python tools/compare_benchmarks.py reports/benchmark.csv other/benchmark.csv [--list]
"""
from __future__ import annotations

import argparse
import csv
import math
import os
import sys

import numpy as np

from contouring_ros.studies.benchmark_report import best_other_rank

KEY = ("scenario", "estimator", "controller", "servo")
NEEDED = ("status", "proposed", "tace_median_um", "tace_verdict", "tace_ratio", "tace_ratio_lo", "tace_ratio_hi", "mce_ratio")


def _float(text: str) -> float:
    try:
        return float(text)
    except (TypeError, ValueError):
        return math.nan


def read_rows(path) -> dict:
    """{(scenario, estimator, controller, servo): row} of a benchmark CSV, the rows that cannot be paired
    left out."""
    with open(path, newline="") as stream:
        reader = csv.DictReader(stream)
        missing = [c for c in KEY + NEEDED if c not in (reader.fieldnames or ())]
        if missing:
            raise ValueError(f"{path} is not a benchmark CSV: no column {', '.join(missing)}")
        return {tuple(r[k] for k in KEY): r for r in reader if not r["status"].startswith("cannot be paired")}


def _kind(status: str) -> str:
    return status.split(":")[0] if status else "ok"


def best_other(rows: dict, scenario: str):
    """The label of the row the report puts against the proposed method in ``scenario``
    (:func:`contouring_ros.studies.benchmark_report.best_other_rank`, as
    :func:`~contouring_ros.studies.benchmark_report.paper_best` ranks its rows), or None."""
    others = []
    for key, row in rows.items():
        if key[0] != scenario or row["proposed"] == "yes" or row["status"] != "ok":
            continue
        tace, mce = _float(row["tace_ratio"]), _float(row["mce_ratio"])
        if math.isfinite(tace) and math.isfinite(mce):
            others.append((best_other_rank(tace, mce), key))
    return _combination(min(others)[1]) if others else None


def _combination(key: tuple) -> str:
    return f"{key[1]} + {key[2]} / {key[3]}"


def _label(key: tuple) -> str:
    return f"{key[0]} {_combination(key)}"


def compare(a: dict, b: dict, listing: bool = False, say=print) -> dict:
    """Print the comparison of runs ``a`` and ``b`` (:func:`read_rows`) and return its figures."""
    both = [k for k in a if k in b]
    say(f"rows: {len(a)} in A, {len(b)} in B, {len(both)} in both")
    changed = [k for k in both if _kind(a[k]["status"]) != _kind(b[k]["status"])]
    say(f"status changed in {len(changed)} rows")
    for k in changed:
        say(f"  {_label(k)}: {_kind(a[k]['status'])} -> {_kind(b[k]['status'])}")
    ratios = {}
    for k in both:
        ta, tb = _float(a[k]["tace_median_um"]), _float(b[k]["tace_median_um"])
        if math.isfinite(ta) and math.isfinite(tb) and ta > 0:
            ratios[k] = tb / ta
    values = np.array(list(ratios.values()))
    figures = {"rows": len(both), "status_changed": len(changed), "compared": len(values)}
    if len(values):
        q1, median, q3 = np.percentile(values, [25, 50, 75])
        within10 = int(np.sum(np.abs(np.log(values)) <= math.log(1.1)))
        within25 = int(np.sum(np.abs(np.log(values)) <= math.log(1.25)))
        better2, worse2 = int(np.sum(values <= 0.5)), int(np.sum(values >= 2.0))
        figures.update(median=median, q1=q1, q3=q3, within10=within10, within25=within25, better2=better2,
                       worse2=worse2)
        say(f"median TACE over the draws, B / A, {len(values)} rows: median {median:.3g} [quartiles {q1:.3g}, "
            f"{q3:.3g}]; within 10%: {within10}, within 25%: {within25}; B at most half of A: {better2}, "
            f"B at least twice A: {worse2}")
        if listing:
            for k, r in sorted(ratios.items(), key=lambda item: item[1]):
                say(f"  {r:8.3g}  {_label(k)}")
    judged = [k for k in both if a[k]["tace_verdict"] or b[k]["tace_verdict"]]
    flipped = [k for k in judged if a[k]["tace_verdict"] != b[k]["tace_verdict"]]
    figures.update(verdicts=len(judged), verdicts_changed=len(flipped))
    say(f"TACE verdicts against the proposed method: {len(judged) - len(flipped)} of {len(judged)} the same")
    for k in flipped:
        say(f"  {_label(k)}: {a[k]['tace_verdict'] or '-'} {_interval(a[k])} -> "
            f"{b[k]['tace_verdict'] or '-'} {_interval(b[k])}")
    scenarios = sorted({k[0] for k in both})
    same = 0
    say("best other combination per scenario (A | B):")
    for scenario in scenarios:
        first, second = best_other(a, scenario), best_other(b, scenario)
        same += first == second
        say(f"  {scenario}: {first} | {second}{'' if first == second else '   (changed)'}")
    figures.update(scenarios=len(scenarios), best_same=same)
    say(f"the same best other combination in {same} of {len(scenarios)} scenarios")
    return figures


def _interval(row: dict) -> str:
    return f"{_float(row['tace_ratio']):.3g} [{_float(row['tace_ratio_lo']):.3g}, {_float(row['tace_ratio_hi']):.3g}]"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("a", help="the reference run's benchmark.csv")
    parser.add_argument("b", help="the other run's benchmark.csv")
    parser.add_argument("--list", action="store_true", help="also list every row's TACE ratio B / A")
    args = parser.parse_args(argv)
    try:
        a, b = read_rows(args.a), read_rows(args.b)
    except (OSError, ValueError, csv.Error) as error:
        print(f"compare_benchmarks: cannot read the CSVs: {error}", file=sys.stderr)
        return 2
    try:
        compare(a, b, args.list)
    except BrokenPipeError:             # the reader stopped early (| head): no traceback
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 0


if __name__ == "__main__":
    sys.exit(main())
