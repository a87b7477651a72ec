"""``contouring-ros score``: bags scored from their contents alone, as a table or as JSON."""
from __future__ import annotations

import json

from .arguments import experiment_option, seconds
from .reading import scored

__all__ = ["HELP", "OUTPUTS", "add_arguments", "main"]

HELP = "score bags from their contents alone"
#: the options that name what the command writes
OUTPUTS = ()


def add_arguments(parser) -> None:
    """The arguments of ``score``."""
    parser.add_argument("bags", nargs="+")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.add_argument("--from", dest="from_time", type=seconds, default=0.0, metavar="T",
                        help="score only the samples at t >= T seconds (steady state; same keys)")
    experiment_option(parser)


def main(args) -> None:
    """Print the scores of every bag of ``args.bags``, side by side (or as JSON with ``--json``)."""
    from ..records.scoring import format_scores, json_scores
    results = scored(args)
    if args.json:
        print(json.dumps({name: json_scores(scores, run.axes) for name, scores, run in results}, indent=2))
    else:
        if args.from_time:
            print(f"scores of the samples at t >= {args.from_time:g} s")
        print(format_scores([(name, scores) for name, scores, _ in results], results[0][2].axes))
