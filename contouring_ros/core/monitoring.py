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

__all__ = ["Breach", "Monitor", "ControlledStop", "breach_at", "first_breach"]


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

    Call :meth:`check` with each step's values once its estimate is known; the reference of a step j for
    which :meth:`stopping` (j) is True is a :class:`ControlledStop`'s
    (:class:`~contouring_ros.core.feed_control.FeedControl` makes it). The in-process loop and the
    interpolator node call them in the same order, so both give the same references.
    """

    def __init__(self, contour_limit: float, following_limits, delay: int):
        self.contour_limit = float(contour_limit)
        self.following_limits = tuple(float(v) for v in following_limits)
        self.delay = int(delay)
        self.breach = None             # the Breach, once one happened

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


class ControlledStop:
    """The reference of a controlled stop on the path (module docstring), from the plan's state at time
    ``t0`` of ``plan``, the reference of step ``first`` - 1; :meth:`reference` (j) for j >= first."""

    def __init__(self, curve, plan, t0: float, first: int, sample_time: float):
        self.curve, self.plan, self.t0, self.first = curve, plan, float(t0), int(first)
        self.sample_time = float(sample_time)
        self.start, v0, a0 = (float(x) for x in plan(self.t0))
        acceleration, jerk = plan.bounds_at(self.start)
        self.trajectory = None            # None: the plan runs on to its own next stop
        # the feed keeps falling by a0^2 / (2 J) while the deceleration is brought back to zero
        if v0 > 0.0 and not (a0 < 0.0 and v0 <= a0 * a0 / (2.0 * jerk) * (1.0 + 1e-9)):
            from ruckig import ControlInterface, InputParameter, Result, Ruckig, Trajectory
            inp = InputParameter(1)
            inp.control_interface = ControlInterface.Velocity
            inp.current_position, inp.current_velocity, inp.current_acceleration = [0.0], [v0], [a0]
            inp.target_velocity, inp.target_acceleration = [0.0], [0.0]
            inp.max_velocity, inp.max_acceleration, inp.max_jerk = [max(v0, 1e-12)], [acceleration], [jerk]
            trajectory = Trajectory(1)
            if Ruckig(1).calculate(inp, trajectory) in (Result.Working, Result.Finished):
                self.trajectory = trajectory
        stops = np.asarray(getattr(plan, "stops", np.zeros((0, 2))), dtype=float).reshape(-1, 2)
        later = stops[stops[:, 0] >= self.t0, 0]
        self._next_stop = float(later[0]) if later.size else float(plan.duration)
        duration = self.trajectory.duration if self.trajectory is not None else self._next_stop - self.t0
        #: the first step at which the reference rests
        self.rest_step = self.first - 1 + max(1, math.ceil(duration / self.sample_time - 1e-9))

    def reference(self, j: int):
        """The reference of step j >= first: on the stop, then resting where it ended."""
        tau = (j - self.first + 1) * self.sample_time            # from the plan time t0
        if self.trajectory is None:
            return reference(self.curve, self.plan, min(self.t0 + tau, self._next_stop))
        if tau >= self.trajectory.duration:
            s = self.start + self.trajectory.at_time(self.trajectory.duration)[0][0]
            return reference(self.curve, _Held(min(s, self.curve.domain[1])), 0.0)
        p, v, a = self.trajectory.at_time(tau)
        return reference(self.curve, _Held(min(self.start + p[0], self.curve.domain[1]), v[0], a[0]), 0.0)


class _Held:
    """A schedule that gives one state: theta, theta_dot, theta_ddot (the stop's at one step)."""

    def __init__(self, theta: float, theta_dot: float = 0.0, theta_ddot: float = 0.0):
        self.state = (float(theta), float(theta_dot), float(theta_ddot))

    def __call__(self, t):
        return self.state
