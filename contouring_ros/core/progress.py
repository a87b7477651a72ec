"""A count of simulated steps shared by the processes of a sweep, for a progress bar that moves with the
steps rather than with whole chunks of combinations (:func:`contouring_ros.studies.sweep.score_experiments`).

A worker process :func:`attach`\\ es the counter its parent made (a ``multiprocessing.Value``); the
simulation loops add their steps to it every :data:`EVERY` steps (a batch: steps times members). Without a
counter attached (a run alone, a Dask worker) adding costs one comparison.
"""
from __future__ import annotations

__all__ = ["EVERY", "attach", "add", "added"]

EVERY = 256          # steps between two additions of a simulation loop
_shared = None       # the parent's multiprocessing.Value('q'), or None
_added = 0           # what this process has added so far


def attach(counter) -> None:
    """Count this process's steps into ``counter`` (a ``multiprocessing.Value``; None: stop counting)."""
    global _shared, _added
    _shared, _added = counter, 0


def add(steps: int) -> None:
    """Add ``steps`` simulated steps (of one run, or member-steps of a batch)."""
    global _added
    if _shared is not None and steps:
        _added += steps
        with _shared.get_lock():
            _shared.value += steps


def added() -> int:
    """The steps this process has added since it attached."""
    return _added
