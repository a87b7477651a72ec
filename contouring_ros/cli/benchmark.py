"""``contouring-ros benchmark``: every estimator x controller (x servo) on every paper scenario, each gain
tuned under equal constraints on a realistic machine, with intervals (:mod:`contouring_ros.studies.benchmark`);
or its report written from parts that runs saved."""
from __future__ import annotations

import sys

from .arguments import (MAX_BUDGET, MAX_BUDGET_GROWTH, MAX_DRAWS, MAX_SEARCHES, MAX_WORKERS, force_option,
                        scheduler_option, whole)
from ..errors import ConfigError

__all__ = ["HELP", "OUTPUTS", "add_arguments", "main"]

HELP = "every estimator x controller (x servo) on every paper scenario, each gain tuned under equal constraints on " \
       "a realistic machine, with intervals"
#: the options that name what the command writes
OUTPUTS = ("out", "save_part")


def add_arguments(parser) -> None:
    """The arguments of ``benchmark``: what is run, the tuning protocol (its defaults
    :class:`contouring_ros.studies.tuning.Protocol`'s), and where the report and parts go."""
    parser.add_argument("--scenarios", nargs="+", metavar="NAME",
                        help="scenarios (or scenario files) by name or glob, e.g. 'paper000_*' (default: the papers' "
                             "own experiments; the claims' mechanism scenarios with e.g. '*_mech_*')")
    _protocol_options(parser)
    parser.add_argument("--out", default="reports",
                        help="folder for benchmark.md, .csv and the figures (default: reports/)")
    parser.add_argument("--workers", type=whole(1, MAX_WORKERS, "processes"),
                        help=f"processes, 1 to {MAX_WORKERS} (default: one per core; never more than there are "
                             "tasks)")
    parser.add_argument("--save-part", metavar="FILE", help="also keep this run's rows in FILE, to report them with "
                                                            "other parts (e.g. each paper run on another machine)")
    parser.add_argument("--methods", nargs="+", metavar="GLOB",
                        help="only the combinations whose estimator, controller or servo set matches, e.g. 'ilc' "
                             "'mpcc' (and each scenario's proposed combination); with --save-part, a later "
                             "--from-parts puts their rows in place of an earlier full run's")
    parser.add_argument("--checkpoints", metavar="DIR",
                        help="keep each tuned row in DIR (made if missing) as it finishes, and take the rows kept "
                             "there by an earlier run of the same scenario, settings and code instead of tuning them "
                             "again: a run stopped part way goes on where it stopped")
    parser.add_argument("--host", help="the machine's name or description a saved part records (default: none)")
    parser.add_argument("--from-parts", nargs="+", metavar="FILE",
                        help="run nothing: write the report, CSV and figures from parts saved by --save-part")
    scheduler_option(parser)
    force_option(parser)


def _protocol_options(parser) -> None:
    """``--budget``, ``--draws``, ``--searches`` and ``--max-searches``, the tuning protocol's."""
    from ..studies.tuning import Protocol
    parser.add_argument("--budget", type=whole(2, MAX_BUDGET, "evaluations"), default=Protocol.evaluations,
                        help=f"evaluations of each search at most, 2 to {MAX_BUDGET} (default {Protocol.evaluations})")
    parser.add_argument("--draws", type=whole(1, MAX_DRAWS, "draws"), default=Protocol.draws,
                        help=f"noise-seed and model-mismatch draws per tuned combination, 1 to {MAX_DRAWS} (default "
                             f"{Protocol.draws})")
    parser.add_argument("--searches", type=whole(1, MAX_SEARCHES, "searches"), default=Protocol.searches,
                        help="independent searches per combination (seeds 1, 2, ...; the first from the file's "
                             "gains), each of at most --budget evaluations; a row is converged when "
                             f"{Protocol.agree} of them end within {100 * Protocol.agreement:g}%% of the best nominal "
                             "TACE; the robust result with the lowest nominal TACE is kept, the same for every method "
                             f"(1 to {MAX_SEARCHES}, default {Protocol.searches})")
    parser.add_argument("--max-searches", type=whole(1, MAX_SEARCHES, "searches"),
                        help="while a row's searches do not agree, as many more as the agreement lacks run side by "
                             "side, up to this many, the same cap for every method (at least --searches, at most "
                             f"{MAX_SEARCHES}; default {Protocol.max_searches})")
    parser.add_argument("--budget-growth", type=whole(1, MAX_BUDGET_GROWTH, "times the budget"),
                        default=Protocol.budget_growth,
                        help="after --max-searches, while a row's searches still do not agree, rounds of --searches "
                             "new searches with 2x, 4x, ... --budget evaluations each, up to this many times "
                             f"(1 to {MAX_BUDGET_GROWTH}, 1: none; default {Protocol.budget_growth})")


def main(args) -> None:
    """Tune and run every combination (or write the report from ``--from-parts``), writing benchmark.md, .csv
    and the heat map into ``--out``."""
    from ..studies.benchmark_report import main_benchmark
    protocol = _protocol(args)
    command = _command(args, protocol.max_searches)
    _claim_outputs(args)
    if args.from_parts:
        _from_parts(args)
        return
    md, table, png, seconds = main_benchmark(args.scenarios, protocol, args.out, args.workers,
                                             progress=sys.stderr.isatty(), say=_say, command=command,
                                             scheduler=args.scheduler, save_part_to=args.save_part,
                                             host=args.host or "", methods=args.methods or (),
                                             checkpoints=args.checkpoints)
    print(f"wrote {md}, {table} and {png} in {seconds / 60:.1f} min" + (f"; the part in {args.save_part}"
                                                                         if args.save_part else ""))


def _say(message: str) -> None:
    """A line of progress on stderr."""
    print(message, file=sys.stderr, flush=True)


def _protocol(args):
    """The tuning protocol the options give (:class:`contouring_ros.studies.tuning.Protocol`), checked."""
    from ..studies.tuning import Protocol
    if args.budget < 2:
        raise ConfigError(f"--budget {args.budget}: expected at least 2 evaluations per combination")
    if args.draws < 1:
        raise ConfigError(f"--draws {args.draws}: expected at least 1 draw per combination")
    if args.searches < 1:
        raise ConfigError(f"--searches {args.searches}: expected at least 1 search per combination")
    max_searches = args.max_searches if args.max_searches is not None else max(Protocol.max_searches, args.searches)
    if max_searches < args.searches:
        raise ConfigError(f"--max-searches {max_searches}: expected at least --searches ({args.searches})")
    return Protocol(evaluations=args.budget, draws=args.draws, searches=args.searches, max_searches=max_searches,
                    budget_growth=args.budget_growth)


def _command(args, max_searches: int) -> str:
    """The command line the report names: the options that differ from the defaults."""
    from ..studies.tuning import Protocol
    return "contouring-ros benchmark" + (f" --scenarios {' '.join(args.scenarios)}" if args.scenarios else "") \
        + (f" --budget {args.budget}" if args.budget != Protocol.evaluations else "") \
        + (f" --draws {args.draws}" if args.draws != Protocol.draws else "") \
        + (f" --searches {args.searches}" if args.searches != Protocol.searches else "") \
        + (f" --max-searches {max_searches}" if max_searches != Protocol.max_searches else "") \
        + (f" --budget-growth {args.budget_growth}" if args.budget_growth != Protocol.budget_growth else "") \
        + (f" --methods {' '.join(args.methods)}" if args.methods else "")


def _claim_outputs(args) -> None:
    """Claim the report, the table, the heat map, the part and the checkpoints' folder
    (:mod:`contouring_ros.records.outputs`)."""
    from ..records import outputs
    out = outputs.active().claim_folder(args.out, "--out")
    for name, kind in (("benchmark.md", outputs.REPORT), ("benchmark.csv", outputs.BENCHMARK_CSV),
                       ("benchmark_heatmap.png", outputs.PNG)):
        outputs.active().claim(out / name, kind, "--out")
    if args.save_part:
        outputs.active().claim(args.save_part, outputs.PART, "--save-part")
    if args.checkpoints:
        outputs.active().claim_folder(args.checkpoints, "--checkpoints")


def _from_parts(args) -> None:
    """Write the report, the table and the figures from the parts ``--from-parts`` names; nothing is run."""
    from ..studies.benchmark_parts import load_parts
    from ..studies.benchmark_report import write_outputs
    if args.methods or args.scenarios or args.save_part or args.checkpoints:
        raise ConfigError("--from-parts runs nothing: --methods, --scenarios, --save-part and --checkpoints belong "
                          "to the runs that wrote the parts")
    md, table, png = write_outputs(load_parts(args.from_parts), args.out)
    print(f"wrote {md}, {table} and {png} from {len(args.from_parts)} parts")

