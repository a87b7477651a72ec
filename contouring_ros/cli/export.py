"""``contouring-ros export``: every signal of every step of bags, with the exact contour error, as CSV or
Parquet tables (:mod:`contouring_ros.records.export`)."""
from __future__ import annotations

import sys
from pathlib import Path

from .arguments import experiment_option, force_option
from .reading import given
from ..errors import ConfigError

__all__ = ["HELP", "OUTPUTS", "add_arguments", "main"]

HELP = "every signal of every step of bags, with the exact contour error, as tables"
#: the options that name what the command writes
OUTPUTS = ("csv", "parquet")


def add_arguments(parser) -> None:
    """The arguments of ``export``."""
    parser.add_argument("bags", nargs="+")
    parser.add_argument("--csv", metavar="DIR", help="write DIR/<bag>.csv (column names carry units and axis names)")
    parser.add_argument("--parquet", metavar="DIR", help="write DIR/<bag>.parquet (needs pyarrow)")
    experiment_option(parser)
    force_option(parser)


def main(args) -> None:
    """Write the table of every bag of ``args.bags`` into ``--csv`` and/or ``--parquet``, and print its path."""
    from ..records.export import export_bag
    from ..records import outputs
    if args.csv is None and args.parquet is None:
        raise ConfigError("export needs --csv DIR and/or --parquet DIR")
    for option, folder, suffix, kind in (("--csv", args.csv, ".csv", outputs.EXPORT_CSV),
                                         ("--parquet", args.parquet, ".parquet", outputs.PARQUET)):
        if folder is not None:
            outputs.active().claim_folder(folder, option)
            for bag in args.bags:
                outputs.active().claim(Path(folder) / f"{Path(bag).stem}{suffix}", kind, option)
    keywords = given(args)
    for bag in args.bags:
        written, warnings = export_bag(bag, args.csv, args.parquet, **keywords)
        for warning in warnings:
            print(f"warning: {warning}", file=sys.stderr)
        for path in written:
            print(path)
