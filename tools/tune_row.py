"""Tune one benchmark combination in-process and print what each of its independent searches ended with.

How a row of the benchmark converges, or why it does not: the scenario's reference (machine, noise bound,
robustness floor) as the benchmark makes it, then ``--searches`` searches of the row side by side
(``Tuning.search``), each line giving the search's chosen nominal TACE, its point in the tuning space and its
evaluations by outcome (admissible, not checked for robustness because they could not be chosen, over the Ms
bound, refused unrun, ...), then the agreement rule's verdict.

    python tools/tune_row.py paper001_caseIII "tangent_line + variable_gain / pid"
    python tools/tune_row.py paper000_h50 "newton + unit_vector / ismc" --searches 4 --budget 300

``--whole`` tunes the row as the benchmark does (``Tuning.run``: more searches side by side while fewer than
the protocol's agree, up to ``--max-searches``, then the draws); ``--popsize`` sets CMA-ES's first population:

    python tools/tune_row.py paper001_caseIII "osculating_circle + ilc / pid" --whole --popsize 8 --budget 200

``--digest`` also prints a hash of every evaluation's point and figures to the last bit: a change meant to
make tuning faster, not different, leaves it as it was.

``--segments N`` tells why searches that do not agree ended apart: for every other search, N points on the
straight segment from its end to the best search's end, each judged as the search judges a point (nominal
run, robustness runs, noise), and one line saying what lies between. "on a slope" means every point of the
segment is admissible and the TACE falls towards the best: that search stopped where it could still go
down, a shortfall of the search, not another optimum. "over a barrier" means some point between is not
admissible, "over a rise" that the TACE rises on the way: another basin, which more searches may or may not
reach.

    python tools/tune_row.py paper004_saddle "newton + unit_vector / eso_smc" --searches 6 --segments 12
"""
from __future__ import annotations

import argparse
import collections
import dataclasses
import hashlib
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from contouring_ros.studies.benchmark import fit_to_machine, plan, reference_job, scenario_families  # noqa: E402
from contouring_ros.studies.tuner import Tuning, lowest_objective, median_tace, searches_agreement  # noqa: E402
from contouring_ros.studies.tuning import Protocol  # noqa: E402


def kind(evaluation) -> str:
    if evaluation.admissible:
        return "admissible"
    failure = evaluation.outcome.failure
    if failure:
        return failure.split(":")[0].split(" ")[0].replace("Ms", "over Ms")
    if evaluation.outcome.ok and not math.isfinite(evaluation.worst):
        return "not checked"
    return "noisy or saturated"


def counts(evaluations: list, search: int) -> str:
    """Search ``search``'s evaluations by outcome (:func:`kind`), the most frequent first."""
    mine = collections.Counter(kind(e) for e in evaluations if e.search == search)
    return ", ".join(f"{n} {k}" for k, n in mine.most_common())


def found_objective(found) -> float:
    """The objective of the point a search chose (nan: none)."""
    return found.chosen.objective if found.chosen is not None else math.nan


def digest(evaluations: list) -> str:
    """A hash of the evaluations' points, nominal TACEs, worst cases and objectives, every bit of each."""
    text = repr([(e.search, e.unit, sorted(e.gains.items()), repr(e.outcome), e.worst, e.objective) for e in evaluations])
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def segment_verdict(taces: list, admissible: list, tolerance: float = 0.01) -> str:
    """What lies on a segment from a search's end (first) to the best search's end (last), from the nominal
    TACE and admissibility of its points in order: 'on a slope' (all admissible, no rise above ``tolerance``
    of the point before the lowest so far), 'over a barrier' (a point not admissible), else 'over a rise'
    (the largest rise, as a share)."""
    if not all(admissible):
        return f"over a barrier: {sum(1 for a in admissible if not a)} of {len(admissible)} points not admissible"
    rise, lowest = 0.0, taces[0]
    for tace in taces[1:]:
        rise = max(rise, tace / lowest - 1.0)
        lowest = min(lowest, tace)
    if rise <= tolerance:
        return f"on a slope: every point admissible, the TACE falls {taces[0] / taces[-1]:.3g}x towards the best"
    return f"over a rise: every point admissible, the TACE rises {100 * rise:.2g}% on the way"


def segments(tuning, searches: list, n: int) -> None:
    """Print :func:`segment_verdict` for the segment from each search's end to the best one's (``n`` points,
    both ends included), with its TACE profile."""
    ended = [(found.tace, i, found.chosen) for i, found in enumerate(searches) if found.chosen is not None]
    if len(ended) < 2:
        print("segments: fewer than two searches ended at an admissible point")
        return
    _, best_index, best = min(ended, key=lambda item: item[0])
    for _, i, chosen in sorted(ended, key=lambda item: item[0]):
        if i == best_index:
            continue
        start, end = np.asarray(chosen.unit, dtype=float), np.asarray(best.unit, dtype=float)
        units = [list(start + t * (end - start)) for t in np.linspace(0.0, 1.0, n)]
        # each point its own group, so that each is run at every perturbation (none is left unchecked
        # because another is lower)
        judged = tuning.measure([(u, *tuning.space.decode(u)) for u in units], list(range(len(units))))
        taces = [e.outcome.tace if e.outcome.ok else math.inf for e in judged]
        admissible = [e.admissible for e in judged]
        profile = " ".join(f"{t * 1e6:.4g}" + ("" if a else "*") for t, a in zip(taces, admissible))
        print(f"search {i} -> search {best_index}: {segment_verdict(taces, admissible)} "
              f"(TACE in um along it, * not admissible: {profile})")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scenario")
    parser.add_argument("combination", help="a combination's label as the report gives it")
    parser.add_argument("--searches", type=int, default=Protocol.searches)
    parser.add_argument("--budget", type=int, default=Protocol.evaluations, help="evaluations of each search")
    parser.add_argument("--popsize", type=int, default=Protocol.popsize, help="CMA-ES's first population")
    parser.add_argument("--max-searches", type=int, default=Protocol.max_searches,
                        help="with --whole: searches at most, while they do not agree")
    parser.add_argument("--whole", action="store_true", help="the benchmark's whole tuning of the row (Tuning.run)")
    parser.add_argument("--budget-growth", type=int, default=Protocol.budget_growth,
                        help="with --whole: then rounds of longer searches while they do not agree, up to this x")
    parser.add_argument("--digest", action="store_true", help="print a hash of every evaluation's numbers")
    parser.add_argument("--segments", type=int, default=0, metavar="N",
                        help="judge N points from each search's end to the best one's (see above)")
    args = parser.parse_args(argv)
    families = {f.name: f for f in scenario_families()}
    if args.scenario not in families:
        parser.error(f"no scenario {args.scenario!r} (scenarios: {', '.join(families)})")
    family = families[args.scenario]
    combos = {c.label: c for c in plan(family)[0]}
    if args.combination not in combos:
        parser.error(f"no combination {args.combination!r} in {args.scenario} (combinations: {'; '.join(combos)})")
    combo = combos[args.combination]
    protocol = dataclasses.replace(Protocol(), evaluations=args.budget, searches=args.searches, popsize=args.popsize,
                                   max_searches=max(args.max_searches, args.searches), budget_growth=args.budget_growth)
    data = family.data[family.proposed]
    reference = reference_job(data, family.from_time, family.name, protocol)
    noise_limit = protocol.noise_factor * reference.published.noise if reference.published.ok else math.inf
    tuning = Tuning(data, fit_to_machine(data, combo.sections, reference.machine), combo.gain_keys, reference.machine,
                    noise_limit, family.from_time, protocol, f"{family.name} {combo.label}",
                    reference.worst if math.isfinite(reference.worst) else 0.0)
    print(f"{family.name} {combo.label}: {tuning.space.describe()}")
    started = time.process_time()
    if args.whole:
        tuned = tuning.run()
        for i, tace in enumerate(tuned.search_tace):
            print(f"search {i}: {tace * 1e6:.4g} um in {tuned.search_evaluations[i]} evaluations "
                  f"({counts(tuned.evaluations, i)})")
        print(f"{tuned.agreement.describe()}; kept search {tuned.search}: {tuned.status}; "
              f"{time.process_time() - started:.1f} s of CPU")
        if tuned.selection:
            print("picked from (nominal, median over the selection draws) [um]: " + ", ".join(
                f"({nominal * 1e6:.4g}, {median * 1e6:.4g})" for nominal, median in tuned.selection))
        if tuned.nominal is not None:
            print(f"kept: {tuned.point_text}: nominal {tuned.nominal.tace * 1e6:.4g} um, median over "
                  f"the draws {median_tace(tuned.draws) * 1e6:.4g} um")
        if args.digest:
            print(f"digest {digest(tuned.evaluations)}")
        return 0
    searches = tuning.search(list(range(args.searches)))
    for i, found in enumerate(searches):
        where = tuning.space.text(found.chosen.point) if found.chosen is not None else found.status
        lowest = lowest_objective([e for e in tuning.tuned.evaluations if e.search == i])
        worst = found.chosen.worst * 1e6 if found.chosen is not None else math.nan
        print(f"search {i}: {found.tace * 1e6:.4g} um (worst {worst:.4g} um, objective {found_objective(found):.4g}, "
              f"lowest {lowest:.4g}) at {where} ({counts(tuning.tuned.evaluations, i)})")
    print(f"{searches_agreement(searches, protocol).describe()}; {time.process_time() - started:.1f} s of CPU")
    if args.digest:
        print(f"digest {digest(tuning.tuned.evaluations)}")
    if args.segments:
        segments(tuning, searches, max(args.segments, 2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
