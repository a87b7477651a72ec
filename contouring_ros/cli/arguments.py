"""The command line's arguments: the parser (errors on one line), the stated bounds of the numeric options,
the argparse types that check them before any work, and the options several subcommands share."""
from __future__ import annotations

import argparse

__all__ = ["MAX_WORKERS", "MAX_BATCH", "MAX_BUDGET", "MAX_DRAWS", "MAX_SEARCHES", "MAX_SECONDS",
           "MAX_WAIT_SUBSCRIBERS", "EXPERIMENT_HELP", "Parser", "seconds", "whole", "seconds_at_most",
           "magnification", "rate", "domain_id", "force_option", "scheduler_option", "experiment_option"]

# the stated bounds of the numeric options, checked before any work
MAX_WORKERS = 256         # --workers: processes (a pool never starts more than it has tasks)
MAX_BATCH = 10_000        # sweep --batch: combinations per vectorised batch
MAX_BUDGET = 100_000      # benchmark --budget: evaluations per combination
MAX_DRAWS = 1_000         # benchmark --draws
MAX_SEARCHES = 100        # benchmark --searches
MAX_BUDGET_GROWTH = 64    # benchmark --budget-growth: times --budget the longest searches get
MAX_SECONDS = 1e9         # any time option (about 32 years)
MAX_WAIT_SUBSCRIBERS = 1_000

#: the help of ``--experiment``, the option of every subcommand that reads bags
EXPERIMENT_HELP = "experiment YAML, for bags recorded without one (e.g. by ros2 bag record)"


class Parser(argparse.ArgumentParser):
    """argparse's parser with its errors on one line (the usage is one --help away)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {' '.join(message.split())} (see {self.prog} --help)\n")


def seconds(text: str) -> float:
    """A non-negative finite time in seconds, at most MAX_SECONDS (argparse type)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds, got {text!r}") from None
    if not 0.0 <= value <= MAX_SECONDS:
        raise argparse.ArgumentTypeError(f"expected a number of seconds from 0 to {MAX_SECONDS:g}, got {text!r}")
    return value


def whole(low: int, high: int, what: str):
    """An argparse type: a whole number of ``what`` from ``low`` to ``high``."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or not low <= value <= high:
            raise argparse.ArgumentTypeError(f"expected a whole number of {what} from {low} to {high}, got {text!r}")
        return value
    return parse


def seconds_at_most(limit: float):
    """An argparse type: a number of seconds from 0 to ``limit``."""
    def parse(text: str) -> float:
        value = seconds(text)
        if value > limit:
            raise argparse.ArgumentTypeError(f"expected a number of seconds from 0 to {limit:g}, got {text!r}")
        return value
    return parse


def magnification(text: str) -> float:
    """A contour error magnification: a positive factor up to 1e9 (argparse type)."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0.0 < value <= 1e9:
        raise argparse.ArgumentTypeError(f"expected a positive magnification up to 1e9, got {text!r}")
    return value


def rate(text: str) -> float:
    """A playback rate: 0 (as fast as possible) or a finite positive factor (argparse type)."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value == 0.0 or 1e-6 <= value <= 1e6):
        raise argparse.ArgumentTypeError("expected 0 (as fast as possible) or a positive factor from 1e-6 to 1e6, got "
                                         f"{text!r}")
    return value


def domain_id(text: str) -> int:
    """A ROS domain id, 0 to 232 (argparse type)."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value <= 232:
        raise argparse.ArgumentTypeError(f"expected a ROS domain id from 0 to 232, got {text!r}")
    return value


def force_option(parser) -> None:
    """``--force``: a command may replace a file that is not its own kind of output (never one of its inputs)."""
    parser.add_argument("--force", action="store_true",
                        help="replace an existing file that is not this command's own kind of output (never one "
                             "of its inputs)")


def scheduler_option(parser) -> None:
    """``--scheduler ADDRESS``: a Dask distributed cluster instead of local processes."""
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="run on the Dask distributed cluster whose scheduler is at ADDRESS (e.g. "
                             "tcp://10.0.0.5:8786) instead of local processes; same results (--workers is then "
                             "the cluster's thread count)")


def experiment_option(parser) -> None:
    """``--experiment FILE``: the experiment of bags recorded without one."""
    parser.add_argument("--experiment", help=EXPERIMENT_HELP)
