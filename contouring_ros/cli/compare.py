"""``contouring-ros compare``: runs scored side by side, with ratios to a baseline and what their experiments
change."""
from __future__ import annotations

from .arguments import experiment_option
from .reading import scored

__all__ = ["HELP", "OUTPUTS", "add_arguments", "main"]

HELP = "score runs side by side, with ratios to a baseline"
#: the options that name what the command writes
OUTPUTS = ()


def add_arguments(parser) -> None:
    """The arguments of ``compare``."""
    parser.add_argument("bags", nargs="+")
    parser.add_argument("--baseline", help="the bag the ratios refer to (default: the first)")
    experiment_option(parser)


def main(args) -> None:
    """Print the comparison of the bags ``args.bags`` (the baseline first) and how their experiments differ."""
    from ..records.comparison import compare_table, experiment_differences, format_differences, run_names
    if args.baseline:
        args.bags = [args.baseline] + [bag for bag in args.bags if bag != args.baseline]
    results = scored(args)
    runs = [(label, run) for label, _, run in results]
    names = run_names(runs)       # the experiment's name (with what --set changed), the bag's time where needed
    print(compare_table([(name, scores) for name, (_, scores, _) in zip(names, results)], 0, results[0][2].axes))
    differ = format_differences(names, experiment_differences(runs))
    if differ:
        print()
        print(differ)
