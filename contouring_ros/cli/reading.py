"""Bags as the subcommands read them: the experiment ``--experiment`` gives for bags recorded without one,
parsed once for every bag; the reader's warnings on stderr; every bag of a command line scored."""
from __future__ import annotations

import sys
from pathlib import Path

__all__ = ["warn", "given", "scored"]


def warn(run) -> None:
    """A run's warnings (what its reader noticed), one line each on stderr."""
    for warning in run.warnings:
        print(f"warning: {warning}", file=sys.stderr)


def given(args) -> dict:
    """The reader's keywords for ``--experiment FILE`` (bags recorded without one): the file's text and its
    Experiment, parsed here once for every bag (see :func:`contouring_ros.records.scoring.read_run`); none without it."""
    if getattr(args, "experiment", None) is None:
        return {}
    from ..experiment.files import load_experiment
    experiment = load_experiment(args.experiment)
    return {"experiment_text": experiment.text, "parsed": experiment}


def scored(args) -> list:
    """[(the bag's stem, Scores, RecordedRun)] of every bag of ``args.bags`` (of the samples at t >= ``--from``
    where the command has it), each run's warnings printed."""
    from ..records.scoring import score_bag
    keywords = given(args)
    start = getattr(args, "from_time", 0.0) or 0.0
    results = [(Path(bag).stem, *score_bag(bag, progress=sys.stderr.isatty(), from_time=start, **keywords))
               for bag in args.bags]
    for _, _, run in results:
        warn(run)
    return results
