"""``contouring-ros blocks``: the results per block of tool path runs, and the scores of their cutting moves
(:mod:`contouring_ros.records.blocks`)."""
from __future__ import annotations

import sys
from pathlib import Path

from .arguments import experiment_option, force_option
from .reading import given, warn
from ..errors import ConfigError

__all__ = ["HELP", "OUTPUTS", "add_arguments", "main"]

HELP = "results per block of tool path runs, and the scores of their cutting moves"
#: the options that name what the command writes
OUTPUTS = ("csv",)


def add_arguments(parser) -> None:
    """The arguments of ``blocks``."""
    parser.add_argument("bags", nargs="+")
    parser.add_argument("--csv", metavar="DIR", help="also write <bag>_blocks.csv per bag into DIR")
    experiment_option(parser)
    force_option(parser)


def _csv_path(args, bag) -> Path:
    """Where ``--csv`` writes the blocks of ``bag``."""
    return Path(args.csv) / f"{Path(bag).stem}_blocks.csv"


def main(args) -> None:
    """Print the blocks of every bag of ``args.bags`` (and write them as CSV with ``--csv``)."""
    from ..records import outputs
    if args.csv:
        outputs.active().claim_folder(args.csv, "--csv")
        for bag in args.bags:
            outputs.active().claim(_csv_path(args, bag), outputs.BLOCKS_CSV, "--csv")
    keywords = given(args)
    for bag in args.bags:
        _blocks_of(args, bag, keywords)


def _blocks_of(args, bag, keywords: dict) -> None:
    """Print the blocks of one ``bag`` (read with the reader's ``keywords``), and write them with ``--csv``."""
    from dataclasses import replace

    from ..records.blocks import block_results, format_blocks, write_blocks_csv
    from ..experiment.build import build_schedule
    from ..records.scoring import curve_of, cutting_lines, motion_steps, read_run
    run = read_run(bag, progress=sys.stderr.isatty(), **keywords)
    warn(run)
    curve = curve_of(run)
    if not hasattr(curve, "blocks"):
        raise ConfigError(f"{bag}: not a tool path run (curve type gcode or toolpath): it has no blocks")
    experiment = replace(run.require_experiment(), path=str(bag))      # named after the bag in messages
    rows = block_results(curve, run.result, build_schedule(experiment, curve),
                         experiment.schedule.get("contour_tolerance") or 0.0,
                         end=motion_steps(curve, run.result, experiment))
    print(f"{bag}:")
    for line in cutting_lines(curve, run.result, experiment):
        print(line)
    print(format_blocks(rows, run.axes, curve, experiment.sample_time))
    if args.csv:
        print(write_blocks_csv(rows, run.axes, _csv_path(args, bag), curve, experiment.sample_time))
