"""The contouring-ros command line: run an experiment through the node graph or simulate it in-process;
score, compare, export, plot and replay its bags; sweep its keys; measure the papers' claims; benchmark
every estimator and controller on every paper scenario."""
from __future__ import annotations

import os
import sys
from pathlib import Path

from . import benchmark, blocks, compare, export, paper, plot, replay, run, score, simulate, sweep
from .arguments import Parser
from ..errors import ContouringError
from ..experiment.scenarios import experiment_path

__all__ = ["VERBS", "build_parser", "main"]

#: the subcommands by name, in the order --help lists them: each a module with its one-line ``HELP``, the
#: ``OUTPUTS`` options that name what it writes, ``add_arguments(parser)`` and ``main(args)``; a subcommand's
#: own work is imported by its ``main`` when it runs
VERBS = {"run": run, "simulate": simulate, "score": score, "blocks": blocks, "compare": compare, "replay": replay,
         "plot": plot, "export": export, "sweep": sweep, "paper": paper, "benchmark": benchmark}


def build_parser() -> Parser:
    """The parser of the command line: one subparser per verb of :data:`VERBS`."""
    parser = Parser(prog="contouring-ros", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    for name, verb in VERBS.items():
        p = sub.add_parser(name, help=verb.HELP)
        verb.add_arguments(p)
        p.set_defaults(func=verb.main)
    return parser


def _inputs(args) -> list:
    """The files a command reads, as named on its command line (its experiment file by scenario name too):
    never replaced by its outputs (:mod:`contouring_ros.records.outputs`)."""
    found = []
    for key, value in vars(args).items():
        if key in VERBS[args.command].OUTPUTS or key == "func":
            continue
        for item in value if isinstance(value, list) else [value]:
            if not isinstance(item, str) or not item or "\0" in item:
                continue
            try:
                path = experiment_path(item) if key == "config" else Path(item)
                if path.is_file():
                    found.append(path)
            except (OSError, ContouringError, ValueError):
                continue
    return found


def main(argv=None) -> int:
    """Run the command line ``argv`` (default: the process's); the exit status: 0, 2 for an error of one line
    on stderr, 130 when interrupted."""
    args = build_parser().parse_args(argv)
    try:
        from ..records.outputs import Outputs
        if getattr(args, "scheduler", None):     # before any work: one line within 30 s if it is not one
            from ..studies.executors import probe_scheduler
            probe_scheduler(args.scheduler)
        with Outputs(_inputs(args), force=getattr(args, "force", False)):
            args.func(args)
    except ContouringError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:        # output piped into head and the like
        sys.stdout = open(os.devnull, "w")
        return 0
    return 0
