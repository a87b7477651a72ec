"""Feed planning over a whole tool path: look-ahead across blocks, jerk-limited (S-curve) feed profiles,
corner handling, and a contour-tolerance planner.

The path is a :class:`~contouring_ros.core.curves.ToolPath` parametrised by arc length s, so the curve
parameter is s itself: theta = s, theta_dot = v (the feed), theta_ddot = dv/dt.

1. Feed limit of each block (:func:`block_limits`): its programmed F (the schedule's ``feedrate`` where the
   program has none; the ``rapid_feedrate`` on G0), the axes' own velocity, acceleration and jerk bounds
   projected on a line's direction (an axis k of bound A_k allows A_k / |u_k| along u), and on arcs the
   centripetal bounds v^2 kappa <= A_n and v^3 kappa^2 <= J (the acceleration and jerk of uniform circular
   motion), and the contour-tolerance cap (:func:`tolerance_feed`) where a tolerance is given.
2. Junction speeds: 0 at the path's ends and at every corner (exact stop, as G61); where two blocks meet
   tangentially (a blend arc, a line into a tangent arc) the lower of their limits.
3. Look-ahead: a forward and a backward pass lower each junction speed to what a jerk-limited profile can
   reach from its neighbour within the block between them (:func:`reach`).
4. One time-optimal jerk-limited profile per block between its junction speeds (zero acceleration at both
   ends, so acceleration is continuous across blocks), computed by Ruckig (Berscheid and Kroeger,
   "Jerk-limited Real-time Trajectory Generation with Arbitrary Target States", RSS 2021), bounded by the
   block's feed, acceleration and jerk limits.
"""
from __future__ import annotations

import copy

import math
from dataclasses import dataclass

import numpy as np

from .curves import ToolPath

__all__ = ["FeedPlan", "BlockLimit", "block_limits", "scurve_time", "scurve_distance", "reach", "tolerance_feed",
           "TANGENT_COSINE"]

TANGENT_COSINE = math.cos(1e-6)      # two blocks meet tangentially when their tangents differ by under 1 urad


def scurve_time(dv: float, acceleration: float, jerk: float) -> float:
    """Shortest time of a jerk-limited change of speed by ``dv`` starting and ending at zero acceleration.

    The classic seven-phase S-curve (e.g. Biagiotti and Melchiorri, "Trajectory Planning for Automatic
    Machines and Robots", Springer 2008, section 3.4): with A^2 / J <= dv the acceleration ramps up in A / J,
    holds at A, ramps down: T = dv / A + A / J; otherwise it never reaches A: T = 2 sqrt(dv / J).
    """
    dv = abs(dv)
    if dv * jerk >= acceleration * acceleration:
        return dv / acceleration + acceleration / jerk
    return 2.0 * math.sqrt(dv / jerk)


def scurve_distance(v0: float, v1: float, acceleration: float, jerk: float) -> float:
    """Distance covered by that change of speed from v0 to v1: the acceleration profile is symmetric in
    time, so the mean speed is (v0 + v1) / 2."""
    return 0.5 * (v0 + v1) * scurve_time(v1 - v0, acceleration, jerk)


def reach(v0: float, length: float, cap: float, acceleration: float, jerk: float) -> float:
    """The highest speed (at most ``cap``) a jerk-limited profile can reach from ``v0`` within ``length``."""
    if cap <= v0 or scurve_distance(v0, cap, acceleration, jerk) <= length:
        return cap
    lo, hi = v0, cap
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if scurve_distance(v0, mid, acceleration, jerk) <= length:
            lo = mid
        else:
            hi = mid
    return lo


def tolerance_feed(tolerance: float, lags, tangent, curvature: float) -> float:
    """The highest feed at which the predicted contour error stays within ``tolerance`` [m].

    Model: each axis k follows its reference as a first-order lag 1 / (tau_k s + 1) (a position loop of
    gain Kp around a velocity drive: tau = 1 / Kp). Two errors add up:

    - on a circle of curvature kappa at feed v (angular rate w = v kappa) every axis lags by the same
      amplitude ratio |1 / (1 + j w tau)| = 1 / sqrt(1 + w^2 tau^2), so the tool runs on a circle short of
      the programmed one by R (1 - 1 / sqrt(1 + w^2 tau^2)) <= R w^2 tau^2 / 2 = v^2 tau^2 kappa / 2 (the
      classic radial error of lagging axes, e.g. Koren, "Computer Control of Manufacturing Systems", 1983,
      ch. 9); with unequal lags the largest tau is taken;
    - unequal lags turn the steady lag vector v diag(tau) t off the tangent t: its component normal to the
      path, v |diag(tau) t - (t . diag(tau) t) t|, is the contour error of a line (Koren 1980, "Cross-
      coupled biaxial computer control for manufacturing systems"); on an arc, whose tangent turns through
      every direction of its plane, it is bounded by v (tau_max - tau_min) / 2.

    The feed solves e(v) = v^2 kappa tau_max^2 / 2 + v c = tolerance, c the normal lag per unit feed.
    """
    lags = np.asarray(lags, dtype=float)
    tangent = np.asarray(tangent, dtype=float)
    if curvature > 0.0:
        c = 0.5 * float(lags.max() - lags.min())
        a = 0.5 * curvature * float(lags.max()) ** 2
    else:
        lagged = lags * tangent
        c = float(np.linalg.norm(lagged - np.dot(tangent, lagged) * tangent))
        a = 0.0
    if a > 0.0:
        return (-c + math.sqrt(c * c + 4.0 * a * tolerance)) / (2.0 * a)
    return tolerance / c if c > 1e-12 * float(lags.max()) else math.inf


@dataclass(frozen=True)
class BlockLimit:
    """A block's feed, acceleration and jerk limits along the path and the bound that set its feed."""

    feed: float
    acceleration: float
    jerk: float
    bound: str          # "F", "rapid", "feedrate", "axis", "centripetal", "tolerance"


def block_limits(path: ToolPath, acceleration: float, jerk: float, feedrate: float | None = None,
                 rapid_feedrate: float | None = None, normal_acceleration: float = 0.0, axis_feedrate=None,
                 axis_acceleration=None, axis_jerk=None, contour_tolerance: float = 0.0,
                 tracking_lag=None) -> list:
    """Step 1 of the module docstring: one :class:`BlockLimit` per block of ``path``."""
    n = path.dimension
    per_axis = [np.full(n, np.inf) if v is None else np.broadcast_to(np.asarray(v, dtype=float), (n,))
                for v in (axis_feedrate, axis_acceleration, axis_jerk)]
    out = []
    for block in path.blocks:
        if block.kind == "rapid":
            if not rapid_feedrate:
                raise ValueError(f"line {block.line}: a rapid move (G0) needs the schedule's rapid_feedrate")
            feed, bound = rapid_feedrate, "rapid"
        elif block.feed is not None:
            feed, bound = block.feed, "F"
        elif feedrate:
            feed, bound = feedrate, "feedrate"
        else:
            raise ValueError(f"line {block.line}: no feed rate (an F word, or the schedule's feedrate)")
        a, j = acceleration, jerk
        if block.curvature == 0.0:
            u = np.abs(block.tangent_in)
            with np.errstate(divide="ignore"):
                axis_v, axis_a, axis_j = (float(np.min(limit / u)) for limit in per_axis)
        else:       # the tangent turns: the tightest axis bounds every direction
            axis_v, axis_a, axis_j = (float(np.min(limit)) for limit in per_axis)
        a, j = min(a, axis_a), min(j, axis_j)
        if axis_v < feed:
            feed, bound = axis_v, "axis"
        if block.curvature > 0.0:
            kappa = block.curvature
            centripetal = min(math.sqrt((normal_acceleration or a) / kappa), (j / kappa**2) ** (1.0 / 3.0))
            if centripetal < feed:
                feed, bound = centripetal, "centripetal"
        if contour_tolerance > 0.0:
            lags = np.broadcast_to(np.asarray(tracking_lag, dtype=float), (n,))
            capped = tolerance_feed(contour_tolerance, lags, block.tangent_in, block.curvature)
            if capped < feed:
                feed, bound = capped, "tolerance"
        out.append(BlockLimit(feed, a, j, bound))
    return out


class FeedPlan:
    """theta(t) along a tool path: the look-ahead, jerk-limited feed plan of the module docstring.

    Parameters
    ----------
    path : ToolPath
    acceleration, jerk : float
        Bounds along the path [m/s^2, m/s^3] (and the centripetal bounds on arcs).
    feedrate : float or None
        Feed [m/s] of blocks the program gives no F (None: every feed block must have one).
    rapid_feedrate : float or None
        Feed of G0 blocks [m/s].
    normal_acceleration : float
        Centripetal acceleration bound on arcs [m/s^2] (0: ``acceleration``).
    axis_feedrate, axis_acceleration, axis_jerk : sequence or None
        Per-axis bounds (one value per axis).
    dwell : float
        [s] Hold at each exact-stop corner before the next block starts, so that the axes settle there (the
        in-position check of an exact stop).
    contour_tolerance : float
        [m] 0: none; else the contour-tolerance planner lowers each block's feed to
        :func:`tolerance_feed` with the axes' ``tracking_lag`` [s] (one value, or one per axis).

    Attributes
    ----------
    limits : list of BlockLimit
    junctions : ndarray
        Planned speed at each block boundary (n_blocks + 1 values).
    block_times : ndarray
        Start time of each block, then the duration.
    """

    #: runs on a batch of times (:mod:`contouring_ros.core.batch`) when every experiment of the batch has the
    #: same plan (its trajectories follow from the shared limits, junction speeds and block times)
    batchable = True
    batch_shared = ("limits", "junctions", "_dwell", "block_times", "_starts")
    batch_kept = ("_trajectories",)

    def __init__(self, path: ToolPath, acceleration: float, jerk: float, feedrate: float | None = None,
                 rapid_feedrate: float | None = None, normal_acceleration: float = 0.0, axis_feedrate=None,
                 axis_acceleration=None, axis_jerk=None, contour_tolerance: float = 0.0, tracking_lag=None,
                 dwell: float = 0.0):
        from ruckig import InputParameter, Result, Ruckig, Trajectory
        if acceleration <= 0.0 or jerk <= 0.0:
            raise ValueError("acceleration and jerk must be positive")
        if contour_tolerance > 0.0 and tracking_lag is None:
            raise ValueError("a contour_tolerance needs the axes' tracking_lag")
        self.curve = path
        self.contour_tolerance = float(contour_tolerance)
        self.theta_start, self.theta_end = path.domain
        blocks = path.blocks
        self.limits = block_limits(path, acceleration, jerk, feedrate, rapid_feedrate, normal_acceleration,
                                   axis_feedrate, axis_acceleration, axis_jerk, contour_tolerance, tracking_lag)
        m = len(blocks)
        v = np.zeros(m + 1)
        corner = np.zeros(m, dtype=bool)             # block i starts at a corner (an exact stop)
        for i in range(1, m):
            if float(np.dot(blocks[i - 1].tangent_out, blocks[i].tangent_in)) >= TANGENT_COSINE:
                v[i] = min(self.limits[i - 1].feed, self.limits[i].feed)
            else:
                corner[i] = True
        for i in range(m):                       # forward: what block i can reach from its entry speed
            lim = self.limits[i]
            v[i + 1] = min(v[i + 1], reach(v[i], blocks[i].length, max(v[i + 1], v[i]), lim.acceleration, lim.jerk))
        for i in range(m - 1, -1, -1):           # backward: what it can brake to its exit speed from
            lim = self.limits[i]
            v[i] = min(v[i], reach(v[i + 1], blocks[i].length, max(v[i], v[i + 1]), lim.acceleration, lim.jerk))
        self.junctions = v
        self._trajectories = []
        self._dwell = np.where(corner, float(dwell), 0.0)
        times = [0.0]
        generator = Ruckig(1)
        for i, block in enumerate(blocks):
            lim = self.limits[i]
            inp = InputParameter(1)
            inp.current_position, inp.current_velocity, inp.current_acceleration = [0.0], [float(v[i])], [0.0]
            inp.target_position, inp.target_velocity, inp.target_acceleration = \
                [block.length], [float(v[i + 1])], [0.0]
            inp.max_velocity, inp.max_acceleration, inp.max_jerk = [lim.feed], [lim.acceleration], [lim.jerk]
            trajectory = Trajectory(1)
            result = generator.calculate(inp, trajectory)
            if result not in (Result.Working, Result.Finished):
                raise ValueError(f"line {block.line}: no jerk-limited profile for this block ({result})")
            extrema = trajectory.position_extrema[0]
            if extrema.min < -1e-12 or extrema.max > block.length + 1e-12:
                raise ValueError(f"line {block.line}: the planned profile would reverse along the path")
            self._trajectories.append(trajectory)
            times.append(times[-1] + self._dwell[i] + trajectory.duration)
        self.block_times = np.array(times)
        self._starts = np.array([block.start for block in blocks])
        self.duration = float(times[-1])
        self._table = None

    def __deepcopy__(self, memo):
        """A deep copy sharing the planned trajectories (read only once planned; Ruckig's cannot be copied)."""
        out = copy.copy(self)
        memo[id(self)] = out
        for name, value in vars(self).items():
            if name != "_trajectories":
                setattr(out, name, copy.deepcopy(value, memo))
        return out

    def _one(self, t: float):
        if t >= self.duration:
            return self.theta_end, 0.0, 0.0
        t = max(t, 0.0)
        i = min(int(np.searchsorted(self.block_times, t, side="right")) - 1, len(self._trajectories) - 1)
        into = t - self.block_times[i] - self._dwell[i]
        if into <= 0.0:                   # holding at a corner
            return self._starts[i], 0.0, 0.0
        p, v, a = self._trajectories[i].at_time(into)
        return self._starts[i] + p[0], v[0], a[0]

    def __call__(self, t):
        """theta (= arc length), theta_dot (feed), theta_ddot at time(s) t."""
        if np.ndim(t) == 0:
            return self._one(float(t))
        times, where = np.unique(np.ravel(t), return_inverse=True)      # a batch's steps share one time
        rows = np.array([self._one(float(x)) for x in times])[where].reshape(np.shape(t) + (3,))
        return rows[..., 0], rows[..., 1], rows[..., 2]

    def feed_limit_at(self, theta):
        """The feed limit of the block at arc length(s) theta."""
        i = np.clip(np.searchsorted(self._starts, theta, side="right") - 1, 0, len(self.limits) - 1)
        return np.array([limit.feed for limit in self.limits])[i]

    def feedrate_at(self, curve, theta):
        """The planned feed where the arc length is theta (0 outside the path), from a table of the profile
        sampled every 0.2 ms."""
        if self._table is None:
            t = np.linspace(0.0, self.duration, max(int(self.duration / 2e-4), 2) + 1)
            s, v, _ = self(t)
            self._table = (s, v)
        s, v = self._table
        theta = np.asarray(theta, dtype=float)
        inside = (theta >= self.theta_start) & (theta <= self.theta_end)
        return np.where(inside, np.interp(theta, s, v), 0.0)
