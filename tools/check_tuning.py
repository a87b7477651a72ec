"""Re-tune benchmark combinations with another optimiser, in raw gains, under the same constraints, and compare.

A comparison is only as good as its tuning: if an independent search beats a reported tuned result by much,
the report's tuning is not done. The check here shares nothing with the benchmark's search but the
constraints: scipy's differential evolution (Storn & Price 1997; ``scipy.optimize.differential_evolution``,
its population evaluated as one batch) over the *raw* gains the row's tuning space sets, each on a log scale
``--decades`` either side of its file value (the benchmark searches physical coordinates with IPOP-CMA-ES),
with ``--factor`` times the benchmark's whole budget of a row (its searches x their evaluations). It reads the
rows of a benchmark.csv (or the rows a run with ``--checkpoints DIR`` has kept so far: give the folder), re-tunes
the chosen combinations on the same machine and noise bound, and prints both nominal and median TACE with the
ratio (re-tuned / reported: below 0.9 means the report is beaten by more than 10%); where neither finds a robust
point, the worst TACE over the perturbations of each one's choice (the point such a row shows: its searches
are compared by the lowest objective they reached, which this optimiser in raw gains does not share).

    python tools/check_tuning.py reports/benchmark.csv "paper000_h50:newton + unit_vector / ismc" ...
    python tools/check_tuning.py CHECKPOINT_DIR "paper000_h50:newton + unit_vector / ismc" ...
"""
from __future__ import annotations

import argparse
import csv
import math
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from contouring_ros.studies import benchmark  # noqa: E402
from contouring_ros.core.tuning_space import Dimension, Space  # noqa: E402
from contouring_ros.studies.machine import fit_to_machine  # noqa: E402
from contouring_ros.studies.space import tuning_space  # noqa: E402
from contouring_ros.studies.summaries import interval  # noqa: E402
from contouring_ros.studies.tuner import tune  # noqa: E402
from contouring_ros.studies.tuning import Protocol  # noqa: E402


def raw_space(data: dict, sections: dict, keys: tuple, protocol: Protocol, decades: float, machine: dict) -> Space:
    """Every raw gain the row's own tuning space sets, each log-scaled ``decades`` either side of its file
    value (a gain that is 0 in the file: of the value at the middle of the physical space, on the
    ``machine``, whose loops a space at a chosen Ms is solved on), the lowest end
    meaning off; integers (a horizon, a lead) over the same range as the physical space's."""
    space, validated = tuning_space(data, sections, keys, protocol, machine=machine)
    file_values = space.gains(space.point(validated))
    middle = space.gains(space.decode([0.5] * len(space.dimensions))[0])
    integers = {d.name: d for d in space.dimensions if d.scale == "int"}
    dims = []
    for key, value in file_values.items():
        if isinstance(value, int) and not isinstance(value, bool):
            d = integers.get(key)
            dims.append(Dimension(key, "", d.low if d else 1, d.high if d else max(2 * value, 2), "int"))
            continue
        anchor = abs(value) if value else abs(middle.get(key) or 1.0) or 1.0
        dims.append(Dimension(key, "", anchor * 10.0 ** -decades, anchor * 10.0 ** decades, "log", True))
    names = [d.name for d in dims]
    return Space(tuple(dims), lambda v: {k: (int(v[k]) if isinstance(file_values[k], int) else v[k]) for k in names},
                 lambda s: {k: abs(file_values[k]) for k in names}, "raw log box")


def differential_evolution(objective_many, start, budget: int, seed: int) -> None:
    """scipy's differential evolution over the unit box, each generation one batch, within ``budget``
    evaluations (its population 5 per dimension, Sobol initialisation, no polish)."""
    from scipy.optimize import differential_evolution as de
    n = len(start)
    members = 5 * n
    generations = max(budget // members - 1, 1)

    def batch(x):                                 # (n, S) -> S values
        return np.asarray(objective_many([list(column) for column in np.asarray(x).T]), dtype=float)
    de(batch, [(0.0, 1.0)] * n, popsize=5, maxiter=generations, seed=seed, vectorized=True, updating="deferred",
       polish=False, tol=0.0, init="sobol", x0=np.clip(start, 0.0, 1.0))


def _retune(name: str, label: str, factor: float, decades: float):
    family = next(f for f in benchmark.scenario_families() if f.name == name)
    combos, _ = benchmark.plan(family)
    combo = next(c for c in combos if c.label == label)
    data = family.data[family.proposed]
    protocol = Protocol()
    reference = benchmark.reference_job(data, family.from_time, name, protocol)
    limit = protocol.noise_factor * reference.published.noise
    sections = fit_to_machine(data, combo.sections, reference.machine)
    budget = int(factor * protocol.evaluations * protocol.searches)
    checked = Protocol(evaluations=budget, searches=1, max_searches=1)
    space = raw_space(data, sections, combo.gain_keys, protocol, decades, reference.machine)
    return tune(data, sections, combo.gain_keys, reference.machine, limit, family.from_time, checked,
                f"{name} {label}", optimiser=differential_evolution,
                robust_floor=reference.worst if math.isfinite(reference.worst) else 0.0, space=space)


def reported_rows(source: str) -> dict:
    """{(scenario, combination label): its row as benchmark.csv gives it (the columns this check reads)}, from a
    benchmark.csv or from a ``--checkpoints`` folder's kept rows."""
    if not Path(source).is_dir():
        with open(source, newline="") as stream:
            return {(r["scenario"], f"{r['estimator']} + {r['controller']} / {r['servo']}"): r
                    for r in csv.DictReader(stream)}
    from contouring_ros.studies.checkpoints import SUFFIX, KeptRow
    from contouring_ros.studies.parts import load
    table = {}
    for path in sorted(Path(source).glob(f"*{SUFFIX}")):
        kept = load(path)
        if not isinstance(kept, KeptRow) or kept.tuned.nominal is None:
            continue
        scenario, _, label = kept.where.partition(" ")
        tuned = kept.tuned
        table[(scenario, label)] = {
            "tace_um": f"{tuned.nominal.tace * 1e6:.4g}",
            "tace_median_um": f"{interval([d.tace for d in tuned.draws if d.ok])[0] * 1e6:.4g}",
            "converged": "yes" if tuned.converged else "no",
            "robust_worst": f"{tuned.robust_worst:.6g}"}
    return table


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("csv", help="a benchmark.csv, or the folder of a run's --checkpoints")
    parser.add_argument("rows", nargs="+", help="'scenario:estimator + controller / servo'")
    parser.add_argument("--factor", type=float, default=3.0,
                        help="budget of the check / the benchmark's budget of a row, searches included (default 3)")
    parser.add_argument("--decades", type=float, default=4.0,
                        help="each raw gain's span either side of its file value [decades] (default 4)")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args(argv)
    table = reported_rows(args.csv)
    wanted = [tuple(spec.split(":", 1)) for spec in args.rows]
    for key in wanted:
        if key not in table:
            parser.error(f"{key[0]}: {key[1]}: no such row in {args.csv}")
    with ProcessPoolExecutor(args.workers) as pool:
        jobs = [pool.submit(_retune, name, label, args.factor, args.decades) for name, label in wanted]
        print("| scenario | combination | reported TACE nominal / median [um] | converged | "
              "differential evolution gains | its TACE nominal / median [um] | median ratio |")
        print("|---|---|---|---|---|---|---:|")
        for (name, label), job in zip(wanted, jobs):
            row, tuned = table[(name, label)], job.result()
            if tuned.status.startswith("not robust") and tuned.nominal is not None and row.get("robust_worst"):
                # where no point is robust, a row shows the point of the lowest worst case over the perturbations
                worst = tuned.robust_worst * tuned.nominal.tace * 1e6
                reported = float(row["robust_worst"]) * float(row["tace_um"])
                print(f"| {name} | {label} | {row['tace_um']} / {row['tace_median_um']} (not robust: worst "
                      f"{reported:.4g}) | {row.get('converged', '')} | not robust either | worst {worst:.4g} | "
                      f"{worst / reported:.3g} (worst) |", flush=True)
                continue
            if not tuned.ok:
                print(f"| {name} | {label} | {row['tace_um']} / {row['tace_median_um']} | {row.get('converged', '')} | "
                      f"{tuned.status} | | |")
                continue
            median = interval([d.tace for d in tuned.draws if d.ok])[0] * 1e6
            gains = ", ".join(f"{k} {v:.3g}" for k, v in tuned.gains.items())
            ratio = median / float(row["tace_median_um"]) if row["tace_median_um"] else float("nan")
            print(f"| {name} | {label} | {row['tace_um']} / {row['tace_median_um']} | {row.get('converged', '')} | "
                  f"{gains} | {tuned.nominal.tace * 1e6:.4g} / {median:.4g} | {ratio:.3g} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
