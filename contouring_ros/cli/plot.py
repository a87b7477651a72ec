"""``contouring-ros plot``: PNG figures of one run or a comparison of runs, and a self-contained HTML report
(:mod:`contouring_ros.records.figures`, :mod:`contouring_ros.records.html_report`)."""
from __future__ import annotations

import sys
from pathlib import Path

from .arguments import experiment_option, force_option, magnification
from .reading import given, warn
from ..errors import ContouringError

__all__ = ["HELP", "OUTPUTS", "add_arguments", "main"]

HELP = "PNG figures of one run or a comparison, and an HTML report"
#: the options that name what the command writes
OUTPUTS = ("out",)


def add_arguments(parser) -> None:
    """The arguments of ``plot``."""
    parser.add_argument("bags", nargs="+")
    parser.add_argument("--out", help="directory for the figures (default: next to the first bag)")
    parser.add_argument("--html", action="store_true", help="also write a self-contained report.html")
    parser.add_argument("--magnification", type=magnification, help="contour error magnification in the path plot")
    parser.add_argument("--baseline", help="with --html: the bag the ratios refer to (default: the first)")
    experiment_option(parser)
    force_option(parser)


def main(args) -> None:
    """Draw the runs of ``args.bags`` (the baseline first) into ``--out``, and the report with ``--html``."""
    from ..records.figures import figures, write_figures
    from ..records.html_report import html_report
    from ..records import outputs
    if args.baseline:
        args.bags = [args.baseline] + [bag for bag in args.bags if bag != args.baseline]
    out = outputs.active().claim_folder(args.out or Path(args.bags[0]).with_suffix(""), "--out")
    if args.html:
        outputs.active().claim(out / "report.html", outputs.HTML, "--html")
    runs, scores = _read(args)
    drawn = figures(runs, args.magnification)
    for path in write_figures(runs, out, drawn=drawn):
        print(path)
    if args.html:
        print(html_report(runs, scores, out / "report.html", drawn=drawn))


def _read(args) -> tuple:
    """([(the bag's stem, RecordedRun)], [its Scores, or None]) of every bag: a run that cannot be scored
    (diverged, no steps) is still drawn, with a warning."""
    import numpy as np

    from ..records.scoring import curve_of, read_run, score_run
    keywords = given(args)
    runs, scores = [], []
    for bag in args.bags:
        run = read_run(bag, progress=sys.stderr.isatty(), **keywords)
        warn(run)
        try:
            with np.errstate(all="ignore"):
                scores.append(score_run(curve_of(run), run.result, experiment=run.experiment))
        except (ContouringError, ValueError, ArithmeticError) as error:
            print(f"warning: {bag}: not scored ({error})", file=sys.stderr)
            scores.append(None)
        runs.append((Path(bag).stem, run))
    return runs, scores
