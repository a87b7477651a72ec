"""Run scores (docs/ARCHITECTURE.md, "Scoring"), always from the exact contour error.

MCE = max |e|, TACE = time average of |e| (paper 000 section IV), RMS of e, estimation deviation
|estimate - exact| (max and RMS), per-axis tracking error (max and RMS of R_i - P_i), RMS actuator effort
per axis, and travel time.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .batch import deep_equal
from .geometry import ExactContourError

__all__ = ["Scores", "score", "exact_solver"]

_SOLVERS: list = []      # (curve, its solver) of the curves scored last, the newest first
_SOLVERS_KEPT = 8


@dataclass(frozen=True)
class Scores:
    """Scores of one run. Lengths in metres, effort in command units, time in seconds."""

    mce: float
    tace: float
    rms: float
    estimation_max: float
    estimation_rms: float
    tracking_max: tuple
    tracking_rms: tuple
    effort_rms: tuple
    travel_time: float
    steps: int
    from_time: float = 0.0      # the scores cover t >= from_time [s] (0: the whole run)

    def as_dict(self) -> dict:
        return asdict(self)


def exact_solver(curve) -> ExactContourError:
    """The exact contour error of ``curve`` with its default settings, shared by every curve equal to it
    (:func:`~contouring_ros.core.batch.deep_equal`): a tuning scores thousands of runs of one curve, each run
    building its own curve object, and the solver's dense samples of the curve cost more than a run's query."""
    for known, solver in _SOLVERS:
        try:
            if known is curve or deep_equal(known, curve):
                return solver
        except RecursionError:      # a plugin's curve that refers back to itself: its own solver
            break
    solver = ExactContourError(curve)
    _SOLVERS.insert(0, (curve, solver))
    del _SOLVERS[_SOLVERS_KEPT:]
    return solver


def _rms(x, axis=None):
    return np.sqrt(np.mean(np.square(x), axis=axis))


def score(curve, time, position, reference_position, estimate_vector, command,
          exact: ExactContourError | None = None, theta=None, from_time: float = 0.0) -> tuple[Scores, np.ndarray]:
    """Score a run and return (scores, exact contour error per step [m]).

    With ``from_time`` > 0 only the samples with t >= from_time count (steady-state scores: the start-up
    transient left out); the keys stay the same, ``steps`` counts the samples scored, and ``travel_time``
    stays the whole run's (the path's travel time does not depend on where the scores start).

    Parameters
    ----------
    curve : Curve
        The reference contour; the exact error is the distance to the whole curve.
    time : (m,) step times [s]
    position, reference_position : (m, n) measured and reference axis positions [m]
    estimate_vector : (m, n) the estimator's contour error vector [m]
    command : (m, n) actuator commands
    exact : ExactContourError, optional
        A prebuilt solver for ``curve`` (saves rebuilding its search tree).
    theta : (m,) reference curve parameter, optional
        Where the curve has a ``contour_error_window``, the search is restricted around it.
    from_time : float
        Score only the samples at t >= from_time [s]; a ValueError when there are none.
    """
    # the path's travel time is the whole run's, whatever part of it is scored
    travel = float(time[-1] - time[0]) if len(time) > 1 else 0.0
    if from_time > 0.0:
        kept = np.asarray(time) >= from_time - 1e-9 * max(1.0, abs(from_time))
        if not kept.any():
            raise ValueError(f"no samples at t >= {from_time:g} s (the run ends at t = {time[-1]:g} s)")
        time, position, reference_position, estimate_vector, command = (
            np.asarray(a)[kept] for a in (time, position, reference_position, estimate_vector, command))
        theta = None if theta is None else np.asarray(theta)[kept]
    exact = exact or exact_solver(curve)
    errors = exact(position, near=theta).distance
    estimated = np.linalg.norm(estimate_vector, axis=1)
    deviation = np.abs(estimated - errors)
    tracking = np.abs(reference_position - position)
    scores = Scores(mce=float(np.max(errors)), tace=float(np.mean(errors)), rms=float(_rms(errors)),
                    estimation_max=float(np.max(deviation)), estimation_rms=float(_rms(deviation)),
                    tracking_max=tuple(float(v) for v in tracking.max(axis=0)),
                    tracking_rms=tuple(float(v) for v in _rms(tracking, axis=0)),
                    effort_rms=tuple(float(v) for v in _rms(command, axis=0)),
                    travel_time=travel, steps=int(len(time)), from_time=float(from_time))
    return scores, errors
