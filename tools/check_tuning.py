"""Re-tune benchmark combinations with another optimiser under the same constraints, and compare.

A comparison is only as good as its tuning: if an independent search (bounded Nelder-Mead from several
starts, :func:`contouring_ros.tuning.nelder_mead_restarts`, with ``--factor`` times the benchmark's budget)
beats a reported tuned result by much, the report's tuning is not done. Reads the rows of a benchmark.csv,
re-tunes the chosen combinations on the same machine and noise bound, and prints both nominal and median
TACE with the ratio (re-tuned / reported: below 0.8 means the report is beaten by more than 20%).

    python tools/check_tuning.py reports/benchmark.csv "paper000_h50:newton + unit_vector / ismc" ...
"""
from __future__ import annotations

import argparse
import csv
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from contouring_ros import benchmark  # noqa: E402
from contouring_ros.tuning import Protocol, interval, nelder_mead_restarts, tune  # noqa: E402


def _retune(name: str, label: str, factor: float):
    family = next(f for f in benchmark.scenario_families() if f.name == name)
    combos, _ = benchmark.plan(family)
    combo = next(c for c in combos if c.label == label)
    data = family.data[family.proposed]
    protocol = Protocol()
    reference = benchmark.reference_job(data, family.from_time, name, protocol)
    limit = protocol.noise_factor * reference.published.noise
    checked = Protocol(evaluations=int(protocol.evaluations * factor))
    tuned = tune(data, combo.sections, combo.gain_keys, reference.machine, limit, family.from_time, checked,
                 f"{name} {label}", optimiser=nelder_mead_restarts, robust_floor=reference.worst)
    return tuned


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("csv", help="a benchmark.csv")
    parser.add_argument("rows", nargs="+", help="'scenario:estimator + controller / servo'")
    parser.add_argument("--factor", type=float, default=2.0, help="budget of the check / the benchmark's (default 2)")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args(argv)
    table = {(r["scenario"], f"{r['estimator']} + {r['controller']} / {r['servo']}"): r
             for r in csv.DictReader(open(args.csv))}
    wanted = [tuple(spec.split(":", 1)) for spec in args.rows]
    for key in wanted:
        if key not in table:
            parser.error(f"{key[0]}: {key[1]}: no such row in {args.csv}")
    with ProcessPoolExecutor(args.workers) as pool:
        jobs = [pool.submit(_retune, name, label, args.factor) for name, label in wanted]
        print("| scenario | combination | reported gains | reported TACE nominal / median [um] | "
              "Nelder-Mead restarts gains | its TACE nominal / median [um] | median ratio |")
        print("|---|---|---|---|---|---|---:|")
        for (name, label), job in zip(wanted, jobs):
            row, tuned = table[(name, label)], job.result()
            if not tuned.ok:
                print(f"| {name} | {label} | {row['gains']} | {row['tace_um']} / {row['tace_median_um']} | "
                      f"{tuned.status} | | |")
                continue
            median = interval([d.tace for d in tuned.draws if d.ok])[0] * 1e6
            gains = ", ".join(f"{k} {v:.3g}" for k, v in tuned.gains.items())
            ratio = median / float(row["tace_median_um"]) if row["tace_median_um"] else float("nan")
            print(f"| {name} | {label} | {row['gains']} | {row['tace_um']} / {row['tace_median_um']} | {gains} | "
                  f"{tuned.nominal.tace * 1e6:.4g} / {median:.4g} | {ratio:.3g} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
