"""What a benchmark run with ``--checkpoints DIR`` has tuned so far: per scenario, the rows kept, how many
converged and their CPU time, and each row's searches by what they were compared by (the nominal TACE of
their robust choices, or the lowest objective each reached where none found an admissible point), while the run goes on or
after it stopped.

    python tools/checkpoint_status.py DIR [--rows]
"""
from __future__ import annotations

import argparse
import collections
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from contouring_ros.studies import benchmark  # noqa: E402,F401  (registers the classes a kept row holds)
from contouring_ros.studies.checkpoints import SUFFIX, KeptRow  # noqa: E402
from contouring_ros.errors import ConfigError  # noqa: E402
from contouring_ros.studies.parts import load  # noqa: E402
from contouring_ros.studies.tuner import chosen_point, compared_values, lowest_objective  # noqa: E402
from contouring_ros.studies.tuning import Search  # noqa: E402


def agreement_values(tuned) -> tuple:
    """(what a row's searches were compared by, the value of each search), from the evaluations the row kept:
    each search's choice (``chosen_point``) compared as ``searches_agreement`` compares them."""
    searches = collections.defaultdict(list)
    for evaluation in tuned.evaluations:
        searches[evaluation.search].append(evaluation)
    kept = []
    for i in sorted(searches):
        chosen, robust = chosen_point(searches[i])
        kept.append(Search(chosen, "ok" if robust else "not robust", lowest=lowest_objective(searches[i])))
    return compared_values(kept)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", help="the --checkpoints folder")
    parser.add_argument("--rows", action="store_true", help="also each row: CPU, searches agreeing, their TACEs")
    args = parser.parse_args(argv)
    files = sorted(Path(args.folder).glob(f"*{SUFFIX}"))
    if not files:
        parser.error(f"{args.folder}: no kept rows ({SUFFIX} files) there")
    scenarios = collections.defaultdict(list)
    for path in files:
        try:
            kept = load(path)
        except ConfigError as error:
            print(f"skipped: {error}", file=sys.stderr)
            continue
        if not isinstance(kept, KeptRow):
            print(f"skipped: {path}: not a row kept by --checkpoints (a {type(kept).__name__})", file=sys.stderr)
            continue
        scenario, _, combination = kept.where.partition(" ")
        scenarios[scenario].append((combination, kept.tuned))
    total = converged = 0
    cpu = 0.0
    for scenario, rows in sorted(scenarios.items()):
        tuned = [t for _, t in rows if t.agreement is not None and t.space]      # the report's tuned rows
        agreeing = sum(t.converged for t in tuned)
        seconds = sum(t.cpu for _, t in rows if math.isfinite(t.cpu))
        total, converged, cpu = total + len(tuned), converged + agreeing, cpu + seconds
        print(f"{scenario}: {len(rows)} rows kept, {agreeing} of {len(tuned)} tuned converged, {seconds / 60:.1f} min of CPU")
        if args.rows:
            for combination, t in sorted(rows, key=lambda r: r[0]):
                a = t.agreement
                agreed = f"{a.agreed} of {a.searches}" if a is not None else "-"
                what, values = agreement_values(t) if t.evaluations else ("nominal TACE", t.search_tace)
                shown = ", ".join(f"{v * 1e6:.4g}" for v in values)
                print(f"  {combination}: {t.cpu:.0f} s, {agreed} agree{'' if t.converged else ' (not converged)'}, "
                      f"{t.status.split(':')[0]}; searches' {what} [um] {shown}")
    print(f"in all: {converged} of {total} tuned rows converged, {cpu / 60:.1f} min of CPU")
    return 0


if __name__ == "__main__":
    sys.exit(main())
