"""``contouring-ros sweep``: in-process runs of an experiment over a grid of its keys, ranked by MCE and TACE
(:mod:`contouring_ros.studies.sweep`)."""
from __future__ import annotations

import os
from pathlib import Path

from .arguments import MAX_BATCH, MAX_WORKERS, force_option, scheduler_option, seconds, whole
from ..errors import ConfigError
from ..experiment.scenarios import experiment_path

__all__ = ["HELP", "OUTPUTS", "add_arguments", "main"]

HELP = "in-process runs over a parameter grid, ranked by MCE and TACE"
#: the options that name what the command writes
OUTPUTS = ("out",)


def add_arguments(parser) -> None:
    """The arguments of ``sweep``."""
    parser.add_argument("config")
    parser.add_argument("--grid", action="append", required=True,
                        help="KEY=V1,V2,... (repeatable), e.g. ccc.kp=0.5,1,2 or curve.h=50,100")
    parser.add_argument("--workers", type=whole(1, MAX_WORKERS, "processes"),
                        help=f"processes, 1 to {MAX_WORKERS} (default: one per core; never more than there are "
                             "tasks)")
    parser.add_argument("--batch", type=whole(1, MAX_BATCH, "combinations"), default=None,
                        help=f"at most this many combinations per vectorised batch, 1 to {MAX_BATCH} (default 250; "
                             "1: each alone)")
    parser.add_argument("--from", dest="from_time", type=seconds, default=0.0, metavar="T",
                        help="score only the samples at t >= T seconds (steady state)")
    parser.add_argument("--out", help="CSV of the ranked results (default bags/<experiment>_sweep_<time>.csv)")
    scheduler_option(parser)
    force_option(parser)


def main(args) -> None:
    """Run every combination of ``--grid`` on the experiment ``args.config``, print them ranked and write the
    ranked results to ``--out``."""
    from datetime import datetime
    from ..experiment.files import load_experiment
    import time

    from ..studies.sweep import BATCH, format_sweep, run_sweep, write_sweep_csv
    from ..experiment.settings import parse_grid
    from ..records import outputs
    experiment = load_experiment(experiment_path(args.config))
    if args.batch is not None and args.batch < 1:
        raise ConfigError(f"--batch {args.batch}: expected a positive number of combinations")
    out = Path(args.out or f"bags/{experiment.name}_sweep_{datetime.now():%Y%m%d_%H%M%S}.csv")
    outputs.active().claim(out, outputs.SWEEP_CSV, "--out")
    started = time.monotonic()
    rows = run_sweep(experiment.text, parse_grid(args.grid), args.workers, progress=None,
                     batch=args.batch or BATCH, from_time=args.from_time, scheduler=args.scheduler)
    if args.from_time:
        print(f"scores of the samples at t >= {args.from_time:g} s (steady state)")
    print(format_sweep(rows))
    print(_summary(args, rows, time.monotonic() - started))
    write_sweep_csv(rows, out, experiment.axes)
    print(f"ranked results: {out}")


def _summary(args, rows, elapsed: float) -> str:
    """The sweep's summary line (:func:`contouring_ros.studies.sweep.sweep_summary`), naming the cluster where
    it ran on one."""
    from ..studies.sweep import sweep_summary
    workers = args.workers or os.cpu_count() or 1
    return sweep_summary(rows, elapsed, workers) if not args.scheduler else \
        sweep_summary(rows, elapsed, workers).replace(
            f"on {workers} process{'es' if workers != 1 else ''}", f"on the cluster at {args.scheduler}")
