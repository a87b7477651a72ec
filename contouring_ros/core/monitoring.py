"""Monitoring during a run: contour-error and following-error limits, and the controlled stop on the path a
breach brings (what a CNC's contour monitoring and following-error trip do: Sinumerik's contour monitoring,
LinuxCNC's FERROR / MIN_FERROR per axis).

Each step k the monitor reads what the control has at that step: the estimator's contour error vector (its
length against ``contour_limit``) and each axis' following error |R_i - P_i| (against its
``following_limits``; 0: not monitored). The first step that passes a limit is the breach. The reference
then stops on the path: from the plan's state (s, v, a) at the last reference already given (step k +
delay - 1, the node graph's interpolator publishes ``delay`` steps ahead), a time-optimal jerk-limited stop
to zero feed and zero acceleration within the plan's own acceleration and jerk bounds at that point
(Ruckig's velocity interface: Berscheid and Kroeger, RSS 2021, as the feed plan), so the tool decelerates
along the programmed path, never leaving it; where no stop is possible without the feed reversing (the feed
nearly zero and still falling) the plan runs on to its own next stop. The reference then rests there for the
rest of the run.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .interpolation import reference

__all__ = ["Breach", "Monitor", "breach_at", "first_breach"]


@dataclass(frozen=True)
class Breach:
    """The first step that passed a limit: ``step``, ``what`` (``contour`` or the axis index), the ``error``
    and its ``limit`` [m], and the curve parameter of the reference then (``theta``: it names the block)."""

    step: int
    what: object
    error: float
    limit: float
    theta: float


def breach_at(vector, reference_position, position, contour_limit: float, following_limits) -> tuple | None:
    """(what, error, limit) of the first limit one step's values pass (the contour error first, then the axes in
    order), or None: the one test the monitor applies during a run and :func:`first_breach` on a record."""
    if contour_limit > 0.0:
        error = math.sqrt(sum(float(v) * float(v) for v in vector))
        if not error <= contour_limit:
            return "contour", error, contour_limit
    for i, limit in enumerate(following_limits):
        if limit > 0.0:
            error = abs(float(reference_position[i]) - float(position[i]))
            if not error <= limit:
                return i, error, float(limit)
    return None


def first_breach(result, contour_limit: float, following_limits, steps: int | None = None) -> Breach | None:
    """The first breach in a recorded or simulated run (its estimate, reference and positions), or None."""
    steps = len(result.time) if steps is None else steps
    following = np.asarray(following_limits, dtype=float)
    with np.errstate(invalid="ignore"):
        over = np.zeros(steps, dtype=bool)
        if contour_limit > 0.0:
            over |= ~(np.linalg.norm(np.asarray(result.estimate_vector)[:steps], axis=1) <= contour_limit)
        if np.any(following > 0.0):
            error = np.abs(np.asarray(result.reference_position)[:steps] - np.asarray(result.position)[:steps])
            over |= np.any(~(error <= np.where(following > 0.0, following, np.inf)), axis=1)
    if not over.any():
        return None
    k = int(np.argmax(over))
    what, error, limit = breach_at(result.estimate_vector[k], result.reference_position[k], result.position[k],
                                   contour_limit, following)
    return Breach(k, what, error, limit, float(result.theta[k]))


class Monitor:
    """The monitor of one run (see the module docstring).

    Call :meth:`check` with each step's values once its estimate is known; before computing the reference of
    step j ask :meth:`stopping` (j); while it is False compute the reference as usual and tell
    :meth:`passed` (j, plan time); once True take :meth:`reference` (j). The in-process loop and the
    interpolator node call them in this order, so both give the same references.
    """

    def __init__(self, curve, schedule, contour_limit: float, following_limits, sample_time: float, delay: int):
        self.curve, self.schedule = curve, schedule
        self.contour_limit = float(contour_limit)
        self.following_limits = tuple(float(v) for v in following_limits)
        self.sample_time, self.delay = float(sample_time), int(delay)
        self.breach = None             # the Breach, once one happened
        self._last = (-1, 0.0)         # (step, plan time) of the latest reference computed as usual
        self._stop = None              # (first step of the stop, its start time, the stop's trajectory or None)

    def check(self, k: int, vector, reference_position, position, theta: float) -> Breach | None:
        """Step k's values (``theta``: its reference's curve parameter); returns the breach the first time one
        happens (None otherwise)."""
        if self.breach is not None:
            return None
        found = breach_at(vector, reference_position, position, self.contour_limit, self.following_limits)
        if found is None:
            return None
        self.breach = Breach(k, *found, float(theta))
        return self.breach

    def stopping(self, j: int) -> bool:
        """Whether the reference of step j is the stop's (it starts ``delay`` steps after the breach)."""
        return self.breach is not None and j >= self.breach.step + self.delay

    def passed(self, j: int, t: float) -> None:
        """The reference of step j was computed as usual, at plan time t."""
        self._last = (j, float(t))

    def reference(self, j: int):
        """The reference of step j during and after the stop."""
        if self._stop is None:
            self._stop = self._plan_stop()
        first, s0, trajectory, t0 = self._stop
        tau = (j - first + 1) * self.sample_time            # from the latest reference computed as usual
        if trajectory is None:                  # the plan runs on to its own next stop
            return reference(self.curve, self.schedule, min(t0 + tau, self._next_stop(t0)))
        if tau >= trajectory.duration:
            s = s0 + trajectory.at_time(trajectory.duration)[0][0]
            return reference(self.curve, _Held(min(s, self.curve.domain[1])), 0.0)
        p, v, a = trajectory.at_time(tau)
        return reference(self.curve, _Held(min(s0 + p[0], self.curve.domain[1]), v[0], a[0]), 0.0)

    def _plan_stop(self):
        """(first step, arc length, trajectory or None, plan time) of the stop, from the plan's state at the
        latest reference computed as usual."""
        last, t0 = self._last
        first = last + 1
        s0, v0, a0 = (float(x) for x in self.schedule(t0))
        acceleration, jerk = self.schedule.bounds_at(s0)
        # the feed keeps falling by a0^2 / (2 J) while the deceleration is brought back to zero
        if v0 <= 0.0 or (a0 < 0.0 and v0 <= a0 * a0 / (2.0 * jerk) * (1.0 + 1e-9)):
            return first, s0, None, t0
        from ruckig import ControlInterface, InputParameter, Result, Ruckig, Trajectory
        inp = InputParameter(1)
        inp.control_interface = ControlInterface.Velocity
        inp.current_position, inp.current_velocity, inp.current_acceleration = [0.0], [v0], [a0]
        inp.target_velocity, inp.target_acceleration = [0.0], [0.0]
        inp.max_velocity, inp.max_acceleration, inp.max_jerk = [max(v0, 1e-12)], [acceleration], [jerk]
        trajectory = Trajectory(1)
        if Ruckig(1).calculate(inp, trajectory) not in (Result.Working, Result.Finished):
            return first, s0, None, t0
        return first, s0, trajectory, t0

    def _next_stop(self, t0: float) -> float:
        """The plan's time of its next zero feed after t0 (an exact stop, else the program's end)."""
        stops = np.asarray(getattr(self.schedule, "stops", np.zeros((0, 2))), dtype=float).reshape(-1, 2)
        later = stops[stops[:, 0] >= t0, 0]
        return float(later[0]) if later.size else float(self.schedule.duration)


class _Held:
    """A schedule that gives one state: theta, theta_dot, theta_ddot (the stop's at one step)."""

    def __init__(self, theta: float, theta_dot: float = 0.0, theta_ddot: float = 0.0):
        self.state = (float(theta), float(theta_dot), float(theta_ddot))

    def __call__(self, t):
        return self.state
