"""Interpolation: the curve-parameter schedule theta(t) and the reference it produces.

The reference at time t is R(theta(t)) with velocity R' theta_dot and acceleration
R'' theta_dot^2 + R' theta_ddot (chain rule on paper 000 eq. 3).
"""
from __future__ import annotations

import bisect
import math
import threading
from dataclasses import dataclass, field, fields, is_dataclass, replace

import numpy as np

from .curves import Curve
from .geometry import power_rows

__all__ = ["UniformSchedule", "FeedrateSchedule", "InPositionClock", "Reference", "reference", "ahead_times",
           "reference_ahead", "reference_rows", "step_time", "ReferenceTable", "at_reference"]


def step_time(k: int, sample_time: float) -> float:
    """t_k = k Ts: the one expression every node and the simulation use for a step's time."""
    return k * sample_time


class UniformSchedule:
    """theta moves uniformly in time from ``theta_start`` to ``theta_end`` over ``duration``, then holds.

    Paper 000 section IV: theta = 2 a t / T - a for t in [0, T].
    """

    #: steps elementwise on arrays with a leading batch axis (:mod:`contouring_ros.core.batch`); nothing in a
    #: run writes to it, so one object can serve a batch as it is
    batchable = True
    batch_read_only = True

    def __init__(self, theta_start: float, theta_end: float, duration: float):
        if duration <= 0.0:
            raise ValueError("schedule duration must be positive")
        self.theta_start = float(theta_start)
        self.theta_end = float(theta_end)
        self.duration = float(duration)
        self.rate = (self.theta_end - self.theta_start) / self.duration

    def __call__(self, t):
        """theta, theta_dot, theta_ddot at time(s) t (floats for a float t: the per-step fast path)."""
        if t.__class__ is float or np.ndim(t) == 0:
            t = float(t)
            if t < self.duration:
                return self.theta_start + self.rate * max(t, 0.0), self.rate, 0.0
            return self.theta_end, 0.0, 0.0
        t = np.asarray(t, dtype=float)
        moving = t < self.duration
        theta = np.where(moving, self.theta_start + self.rate * np.clip(t, 0.0, None), self.theta_end)
        theta_dot = np.where(moving, self.rate, 0.0)
        return theta, theta_dot, np.zeros_like(theta)

    def feedrate_at(self, curve: Curve, theta):
        """The feedrate |R'(theta)| theta_dot where the curve parameter is theta (0 outside the range)."""
        lo, hi = np.minimum(self.theta_start, self.theta_end), np.maximum(self.theta_start, self.theta_end)
        inside = (np.asarray(theta) >= lo) & (np.asarray(theta) <= hi)
        return np.where(inside, np.linalg.norm(curve.derivatives(theta, order=1)[1], axis=-1) * abs(self.rate), 0.0)


class FeedrateSchedule:
    """theta(t) that moves along the curve at a commanded feedrate with an acceleration-bounded profile.

    The feedrate v(s) along the arc length s is the largest profile under three bounds: the commanded
    ``feedrate``; on curved stretches sqrt(normal_acceleration / kappa), so the centripetal acceleration
    stays within ``normal_acceleration`` (0: no bound); and |dv/dt| <= ``acceleration``, from rest at the
    start to rest at the end (the classic forward-backward pass over a dense table of ``samples`` points,
    with v^2 linear in s, i.e. constant acceleration, between them; jerk is not bounded). Arc length is
    integrated by the trapezoidal rule on that table. Between table points the motion is evaluated exactly
    under the constant acceleration; theta_dot = v / |R'| and theta_ddot = (dv/dt - theta_dot^2 R'.R''/|R'|)
    / |R'| follow from the chain rule.
    """

    #: runs elementwise on a batch of times (:mod:`contouring_ros.core.batch`) when every experiment of the
    #: batch has the same profile table
    batchable = True
    batch_shared = ("_theta", "_arc", "_v", "_t", "_a")
    batch_read_only = True

    def __init__(self, curve: Curve, theta_start: float, theta_end: float, feedrate: float, acceleration: float,
                 normal_acceleration: float = 0.0, samples: int = 20001):
        if feedrate <= 0.0 or acceleration <= 0.0 or theta_end <= theta_start:
            raise ValueError("feedrate and acceleration must be positive and theta_end above theta_start")
        self.curve = curve
        self.theta_start, self.theta_end = float(theta_start), float(theta_end)
        theta = np.linspace(self.theta_start, self.theta_end, int(samples))
        d = curve.derivatives(theta, order=2)
        speed = np.linalg.norm(d[1], axis=-1)
        arc = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(theta))])
        limit = np.full(theta.size, float(feedrate))
        if normal_acceleration > 0.0:
            d1, d2 = d[1], d[2]
            cross = np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) if curve.dimension == 2 else \
                np.linalg.norm(np.cross(d1, d2), axis=-1)
            kappa = cross / speed**3
            with np.errstate(divide="ignore"):
                limit = np.minimum(limit, np.sqrt(normal_acceleration / kappa))
        step = np.diff(arc)
        v2 = limit**2
        v2[0] = 0.0
        for i in range(1, theta.size):
            v2[i] = min(v2[i], v2[i - 1] + 2.0 * acceleration * step[i - 1])
        v2[-1] = 0.0
        for i in range(theta.size - 2, -1, -1):
            v2[i] = min(v2[i], v2[i + 1] + 2.0 * acceleration * step[i])
        v = np.sqrt(v2)
        dt = 2.0 * step / (v[1:] + v[:-1])
        self._theta, self._arc, self._v = theta, arc, v
        self._t = np.concatenate([[0.0], np.cumsum(dt)])
        self._a = (v[1:] ** 2 - v[:-1] ** 2) / (2.0 * step)
        self.duration = float(self._t[-1])

    def feedrate_at(self, curve: Curve, theta):
        """The profile's feedrate where the curve parameter is theta (0 outside the schedule's range)."""
        return np.interp(theta, self._theta, self._v, left=0.0, right=0.0)

    def __call__(self, t):
        """theta, theta_dot, theta_ddot at time(s) t."""
        if t.__class__ is float:
            return self._at(t)
        t = np.asarray(t, dtype=float)
        i = np.clip(np.searchsorted(self._t, t, side="right") - 1, 0, self._t.size - 2)
        tau = np.clip(t, 0.0, self.duration) - self._t[i]
        a = self._a[i]
        v = self._v[i] + a * tau
        s = self._arc[i] + self._v[i] * tau + 0.5 * a * tau * tau
        fraction = (s - self._arc[i]) / (self._arc[i + 1] - self._arc[i])
        theta = self._theta[i] + fraction * (self._theta[i + 1] - self._theta[i])
        d = self.curve.derivatives(theta, order=2)
        speed = np.linalg.norm(d[1], axis=-1)
        theta_dot = v / speed
        theta_ddot = (a - power_rows(theta_dot, 2) * np.sum(d[1] * d[2], axis=-1) / speed) / speed     # as _at
        done = t >= self.duration
        theta = np.where(done, self.theta_end, theta)
        theta_dot = np.where(done, 0.0, theta_dot)
        theta_ddot = np.where(done, 0.0, theta_ddot)
        if np.ndim(theta) == 0:
            return float(theta), float(theta_dot), float(theta_ddot)
        return theta, theta_dot, theta_ddot

    def _at(self, t: float) -> tuple:
        """:meth:`__call__` at one time: the same operations on Python floats (one step's reference; numpy
        scalars cost more than the arithmetic), the same numbers."""
        if t >= self.duration:
            return self.theta_end, 0.0, 0.0
        times = self._t
        i = min(max(bisect.bisect_right(times, t) - 1, 0), times.size - 2)
        tau = max(t, 0.0) - float(times[i])
        a, v0, arc0 = float(self._a[i]), float(self._v[i]), float(self._arc[i])
        v = v0 + a * tau
        s = arc0 + v0 * tau + 0.5 * a * tau * tau
        fraction = (s - arc0) / (float(self._arc[i + 1]) - arc0)
        theta0 = float(self._theta[i])
        theta = theta0 + fraction * (float(self._theta[i + 1]) - theta0)
        _, d1, d2 = self.curve.columns(theta)[:3]
        d1, d2 = [float(x) for x in d1], [float(x) for x in d2]
        squares, products = d1[0] * d1[0], d1[0] * d2[0]
        for x, y in zip(d1[1:], d2[1:]):
            squares += x * x
            products += x * y
        speed = math.sqrt(squares)
        theta_dot = v / speed
        return theta, theta_dot, (a - theta_dot**2 * products / speed) / speed     # pow(), as numpy scalars take it


#: [s] an axis is in position when within its window and too slow to leave it in less than this (not passing
#: through the window on its way past the corner)
SETTLE = 0.01


class InPositionClock:
    """The time along a feed plan at each step, where every exact stop waits for the axes (the in-position
    check of a CNC's exact stop, G61 / G9: the next block starts once every axis is in position).

    Call :meth:`time` for k = 0, 1, 2, ... in order. The plan's time runs with the steps until it reaches an
    exact stop (``schedule.stops``: the time the feed reaches 0 there and the corner's arc length); there it
    holds, the reference resting on the corner, until every axis is in position: its measured position
    within its ``windows`` [m] of the corner and its speed under window / :data:`SETTLE` (an axis that
    crosses the window on its way past the corner, as an integrating servo's overshoot does, is not in
    position yet); or for at most ``timeout`` [s]; then the plan runs on (through any planned dwell).

    The states a step sees are those measured ``delay`` steps earlier: the node graph's interpolator
    publishes the reference of step k + delay when the estimate of step k arrives, and it takes the axis
    states of step k (docs/ARCHITECTURE.md), so the in-process loop gives it those of step k - delay. Until
    the first stop the time is k Ts exactly, as without the check.
    """

    def __init__(self, schedule, curve, windows, sample_time: float, timeout: float, delay: int):
        stops = np.asarray(schedule.stops, dtype=float).reshape(-1, 2)
        self.stop_times = stops[:, 0]
        self.corners = np.atleast_2d(curve.point(stops[:, 1])) if len(stops) else np.zeros((0, len(windows)))
        self.windows = np.asarray(windows, dtype=float)
        self.sample_time = float(sample_time)
        self.timeout_steps = int(round(timeout / sample_time))
        self.delay = int(delay)
        self._next = 0              # the next stop
        self._held = -1             # the step its hold began, -1 while moving
        self._offset = 0.0          # plan time = k Ts - offset while moving
        self.waits = []             # (stop, steps waited), for the report

    def time(self, k: int, position=None, velocity=None) -> float:
        """The plan's time at step k; ``position``, ``velocity``: every axis' state measured at step
        k - delay (None before the first)."""
        ts = self.sample_time
        if self._held >= 0:
            stop = self._next
            corner_time = self.stop_times[stop]
            in_position = position is not None and \
                bool(np.all(np.abs(np.asarray(position) - self.corners[stop]) <= self.windows)) and \
                bool(np.all(np.abs(np.asarray(velocity)) * SETTLE <= self.windows))
            if not in_position and k - self._held < self.timeout_steps:
                return float(corner_time)
            self.waits.append((stop, k - self._held))
            self._held, self._next = -1, stop + 1
            self._offset = k * ts - (corner_time + ts)
        t = k * ts - self._offset
        if self._next < len(self.stop_times) and t >= self.stop_times[self._next]:
            self._held = k
            return float(self.stop_times[self._next])
        return t

    @property
    def holding(self) -> bool:
        """Whether the reference waits at an exact stop for the axes now."""
        return self._held >= 0

    def ahead(self, t: float, count: int) -> np.ndarray:
        """The plan's times at the ``count`` steps after the one :meth:`time` just gave ``t``, as far as they
        are known now: held at the corner while the axes settle there, else running on with the steps up to
        the next exact stop (where the plan will hold)."""
        if self._held >= 0:
            return np.full(count, float(t))
        times = t + self.sample_time * np.arange(1, count + 1)
        if self._next < len(self.stop_times):
            times = np.minimum(times, self.stop_times[self._next])
        return times


@dataclass(frozen=True)
class Reference:
    """Reference samples; arrays have a leading time axis when built for many times.

    Attributes
    ----------
    theta, theta_dot, theta_ddot : float or ndarray
        Curve parameter and its time derivatives.
    position, velocity, acceleration : ndarray, shape ([m,] n)
        Per-axis reference position [m], velocity [m/s] and acceleration [m/s^2].
    memo : dict or None
        Where the reference comes from a :class:`ReferenceTable`: what :func:`at_reference` has computed
        from it (the same for every run that reads this step); None otherwise.
    """

    theta: np.ndarray
    theta_dot: np.ndarray
    theta_ddot: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    memo: dict | None = field(default=None, compare=False, repr=False)


def at_reference(reference: Reference, function, *arguments):
    """``function(*arguments)``, where ``function`` is pure and its arguments are the curve, constants and
    values of ``reference`` (the Frenet frame at the reference point, the curve's derivatives there):
    computed once per step along a path, for every run that reads the step from a :class:`ReferenceTable`
    (a batch whose reference arrays repeat one row, as a table's do, gets the batch of one's value broadcast
    to its members: one entry for every batch size), and kept read-only; computed each time for any other
    reference (a node's, one computed by its run). A step keeps at most :data:`MEMO_ENTRIES` of them, the
    oldest given up first, and none for other batches of more than :data:`MEMO_BATCH` members (rows taken
    out of a batch by a mixed batch's classes), which would otherwise keep one entry of every size they met,
    each step, for as long as the path."""
    memo = reference.memo
    if memo is None:
        return function(*arguments)
    members = _repeated_rows(arguments)
    if members:          # a batch along a shared path: every member's row is the same, computed for one
        one = at_reference(reference, function, *(a[:1] if a.__class__ is np.ndarray else a for a in arguments))
        return _broadcast_all(one, members)
    key = (function, *(a.shape if a.__class__ is np.ndarray else a for a in arguments))
    value = memo.get(key)
    if value is None:
        value = _frozen_all(function(*arguments))
        if any(a.__class__ is np.ndarray and a.ndim and a.shape[0] > MEMO_BATCH for a in arguments):
            return value
        if len(memo) >= MEMO_ENTRIES:
            try:
                memo.pop(next(iter(memo)), None)
            except (RuntimeError, StopIteration):     # another thread changed it meanwhile: keep it as it is
                pass
        memo[key] = value
    return value


def _repeated_rows(arguments) -> int:
    """The batch size b > 1 where every array among ``arguments`` has a leading axis of b that repeats one
    row (a broadcast view, stride 0: a batch's reference read from a :class:`ReferenceTable`); else 0."""
    members = 0
    for a in arguments:
        if a.__class__ is np.ndarray and a.ndim:
            if a.strides[0] != 0 or a.shape[0] < 2 or members not in (0, a.shape[0]):
                return 0
            members = a.shape[0]
    return members


def _broadcast_all(value, members: int):
    """``value`` (an array, a tuple of them or a dataclass holding them) of a batch of one, its arrays
    broadcast to ``members`` rows (read-only views)."""
    if value.__class__ is np.ndarray:
        return np.broadcast_to(value, (members,) + value.shape[1:]) if value.ndim else value
    if isinstance(value, tuple):
        return tuple(_broadcast_all(item, members) for item in value)
    if is_dataclass(value):
        return replace(value, **{f.name: _broadcast_all(getattr(value, f.name), members) for f in fields(value)})
    return value


MEMO_ENTRIES = 8      # entries a step's memo keeps (at_reference): a few functions at a few batch sizes
MEMO_BATCH = 64       # ... for batches of at most this many members (a larger batch's entry is its own work)


def _frozen_all(value):
    """``value`` with every array in it (in a tuple, or an attribute of an object) read-only."""
    if isinstance(value, np.ndarray):
        return _frozen(value)
    for item in value if isinstance(value, tuple) else getattr(value, "__dict__", {}).values():
        if isinstance(item, np.ndarray):
            _frozen(item)
    return value


def ahead_times(k: int, t: float, count: int, sample_time: float, clock=None) -> np.ndarray:
    """The plan's times of the ``count`` steps after step k (whose time is ``t``): (k + j) Ts, j = 1 .. count,
    as :func:`contouring_ros.core.simulation.step_time` gives them, or the ``clock``'s
    (:meth:`InPositionClock.ahead`)."""
    if clock is not None:
        return clock.ahead(t, count)
    return (k + np.arange(1, count + 1)) * sample_time


def reference_ahead(curve: Curve, schedule, k: int, t: float, count: int, sample_time: float,
                    clock=None) -> Reference:
    """The reference preview of step k: the reference at the ``count`` steps after it (:func:`ahead_times`),
    arrays with a leading axis of ``count``. The interpolator node publishes it with the reference of step k
    and the simulation gives it to the servos that read ahead (ZPETC), the same values in both."""
    return reference(curve, schedule, ahead_times(k, t, count, sample_time, clock))


def reference(curve: Curve, schedule, t) -> Reference:
    """The reference of ``curve`` driven by ``schedule`` at time(s) ``t``."""
    theta, theta_dot, theta_ddot = schedule(t)
    if theta.__class__ is float or np.ndim(theta) == 0:          # one step: the curve's scalar path
        point, d1, d2 = curve.columns(float(theta))[:3]
        rate, accel = float(theta_dot), float(theta_ddot)
        return Reference(theta=theta, theta_dot=theta_dot, theta_ddot=theta_ddot, position=np.array(point, dtype=float),
                         velocity=np.array([v * rate for v in d1]),
                         acceleration=np.array([a * rate * rate + v * accel for a, v in zip(d2, d1)]))
    d = curve.derivatives(theta, order=2)
    rate = np.asarray(theta_dot)[..., None]
    accel = np.asarray(theta_ddot)[..., None]
    return Reference(theta=theta, theta_dot=theta_dot, theta_ddot=theta_ddot, position=d[0],
                     velocity=d[1] * rate, acceleration=d[2] * rate * rate + d[1] * accel)


def reference_rows(curve: Curve, schedule, times) -> Reference:
    """The reference of a batch's members at their times (B, 1): theta and its derivatives (B, 1), positions,
    velocities and accelerations (B, n) (:func:`reference` with the time axis of one dropped)."""
    ref = reference(curve, schedule, times)
    return Reference(ref.theta, ref.theta_dot, ref.theta_ddot, ref.position[:, 0], ref.velocity[:, 0],
                     ref.acceleration[:, 0])


def _frozen(array):
    array = np.asarray(array)
    array.flags.writeable = False
    return array


class ReferenceTable:
    """The reference of every step along one path (curve, schedule, sample time), computed once and kept for
    every run along it: a tuning runs a scenario's path hundreds of times, and each run's reference is the
    same. Step k's entry is what :func:`reference` gives at :func:`step_time` (k, Ts), by the same code
    (the scalar path for a run alone, the batch path for a batch), so a run that reads the table has the
    numbers of one that computes them, bit for bit. Only for a reference on the step time: an in-position
    clock (exact stops waiting for the axes) makes each run's times its own.

    Entries are computed as runs first reach them and kept read-only (a consumer that wrote into a shared
    array would fail at once instead of changing later runs). Safe to read from several threads. At most
    :attr:`KEPT_STEPS` steps are kept per kind of entry: a step past them is computed when asked, by the same
    code (the same numbers), and not kept, so that a long run (an hour at 1 kHz: 3.6 million steps, about
    1.5 kB each as entries) holds its reference only as its result's arrays.
    """

    KEPT_STEPS = 100_000       # steps kept per kind of entry (about 150 MB of scalar-path entries)

    def __init__(self, curve: Curve, schedule, sample_time: float):
        self.curve, self.schedule, self.sample_time = curve, schedule, float(sample_time)
        self._lock = threading.Lock()
        self._steps = []           # Reference of step k, the scalar path
        self._ahead = {}           # count -> the positions (count, n) of the preview of step k, the scalar path
        self._rows = []            # Reference of step k with a leading batch axis of 1, the batch path
        self._rows_ahead = {}      # count -> positions (1, count, n), the batch path
        self._stacked = {}         # steps -> the batch path's rows 0 .. steps - 1 stacked (stacked_rows)

    def __deepcopy__(self, memo):
        return self                # shared by every run along the path (a batch copies its loops)

    def __reduce__(self):
        return ReferenceTable, (self.curve, self.schedule, self.sample_time)     # another process: a fresh table

    def _extend(self, entries: list, k: int, compute) -> object:
        """Entry k of ``entries``, computed (``compute(j)``) up to it first where it is not there yet; past
        KEPT_STEPS computed and not kept."""
        if k >= self.KEPT_STEPS:
            return compute(k)
        if k >= len(entries):
            with self._lock:
                while len(entries) <= k:
                    entries.append(compute(len(entries)))
        return entries[k]

    def at(self, k: int) -> Reference:
        """The reference of step k: ``reference(curve, schedule, step_time(k, Ts))``."""
        return self._extend(self._steps, k, self._one)

    def ahead(self, k: int, count: int) -> np.ndarray:
        """The positions (count, n) of step k's preview: ``reference_ahead(curve, schedule, k, step_time(k,
        Ts), count, Ts).position``."""
        return self._extend(self._ahead.setdefault(count, []), k, lambda j: _frozen(reference_ahead(
            self.curve, self.schedule, j, step_time(j, self.sample_time), count, self.sample_time).position))

    def row(self, k: int) -> Reference:
        """Step k's reference as a batch along the path computes it for each of its members (a batch's curve
        and schedule are the path's own: ``batch_read_only``; the times a column), with a batch axis of one:
        theta (1, 1), position (1, n) ..."""
        return self._extend(self._rows, k, self._row)

    def stacked_rows(self, steps: int) -> tuple:
        """((theta, theta_dot, theta_ddot, position, velocity, acceleration), memos) of :meth:`row` 0 .. steps
        - 1: each field stacked over the steps, (steps, 1, ...), read-only, and each row's memo; computed once
        for every batch along the path (a batch repeats them for its members)."""
        stacked = self._stacked.get(steps)
        if stacked is None:
            rows = [self.row(k) for k in range(steps)]
            stacked = (tuple(_frozen(np.stack([getattr(row, name) for row in rows])) for name in (
                "theta", "theta_dot", "theta_ddot", "position", "velocity", "acceleration")), [row.memo for row in rows])
            self._stacked[steps] = stacked         # two threads at once compute the same arrays
        return stacked

    def row_ahead(self, k: int, count: int) -> np.ndarray:
        """The positions (1, count, n) of step k's preview as a batch computes them."""
        return self._extend(self._rows_ahead.setdefault(count, []), k, lambda j: _frozen(reference(
            self.curve, self.schedule,
            ahead_times(j, step_time(j, self.sample_time), count, self.sample_time)[None, :]).position))

    def _one(self, k: int) -> Reference:
        return _frozen_reference(reference(self.curve, self.schedule, step_time(k, self.sample_time)))

    def _row(self, k: int) -> Reference:
        return _frozen_reference(reference_rows(self.curve, self.schedule, np.full((1, 1), step_time(k, self.sample_time))))


def _frozen_reference(ref: Reference) -> Reference:
    """``ref`` with its arrays read-only and a memo of its own (:func:`at_reference`)."""
    return Reference(*(_frozen(v) if isinstance(v, np.ndarray) else v for v in (
        ref.theta, ref.theta_dot, ref.theta_ddot, ref.position, ref.velocity, ref.acceleration)), {})
