"""Feed planning over a whole tool path: look-ahead across blocks, jerk-limited (S-curve) feed profiles,
junction speeds from the geometry and the limits, and a contour-tolerance planner.

The path is a :class:`~contouring_ros.core.curves.ToolPath` parametrised by arc length s, so the curve
parameter is s itself: theta = s, theta_dot = v (the feed), theta_ddot = dv/dt.

1. Feed limit of each block (:func:`block_limits`): its programmed F (the schedule's ``feedrate`` where the
   program has none; the ``rapid_feedrate`` on G0) times the feed override, the axes' own velocity,
   acceleration and jerk bounds projected on a line's direction (an axis k of bound A_k allows A_k / |u_k|
   along u), and on arcs the centripetal bounds v^2 kappa <= A_n and v^3 kappa^2 <= J (the acceleration and
   jerk of uniform circular motion), and the contour-tolerance cap (:func:`tolerance_feed`) where a
   tolerance is given.
2. Junction speeds (:func:`junction_speed`): 0 at the path's ends, before a G4 dwell and at every corner of
   a block in exact stop (G61, G9: deviation 0); where two blocks meet tangentially (a blend arc, a line into
   a tangent arc) the lower of their limits; at any other corner of a block that may deviate by P (G64 P),
   grbl's junction deviation: the speed at which the axes' acceleration and jerk carry the tool round the
   arc tangent to both blocks that passes within P of the corner.
3. Spans: consecutive blocks with the same limits, meeting at junctions that allow their whole feed, are
   one span (a polygon of short chords at one F is one span), so the feed is not brought to zero
   acceleration at every short block; so is a block whose own feed is higher than the span's but too short
   to use it (:func:`joins_span`: the blend arcs and chords of a CAM program's rounded coordinates, each at a
   feed of its own); the look-ahead runs on spans: a forward and a backward pass lower
   each span boundary's speed to what a jerk-limited profile can reach from its neighbour within the span
   (:func:`reach`, in closed form). Both passes are linear in the number of blocks. With a look-ahead of W
   blocks (``lookahead_blocks``, a control's block queue) spans are at most W / 2 blocks and each span's
   exit speed is fixed from the W blocks ahead of its start alone, the last taken to end in a stop
   (:meth:`FeedPlan._windowed`): its duration is never shorter than the whole program's plan's (block by
   block it can be faster, where the whole plan brakes early for a slow corner: see the README).
   :mod:`.feed_stream` makes the same plan while it reads the program, holding only the window.
4. One time-optimal jerk-limited profile per span between its boundary speeds (zero acceleration at both
   ends, so acceleration is continuous across spans), computed by Ruckig (Berscheid and Kroeger,
   "Jerk-limited Real-time Trajectory Generation with Arbitrary Target States", RSS 2021), bounded by the
   span's feed, acceleration and jerk limits; the reach leaves each span a relative 1e-9 of its length
   spare, so no profile has to overshoot the span's end and come back: the feed never reverses.
"""
from __future__ import annotations

import copy
import dataclasses
import math
from array import array
from dataclasses import dataclass

import numpy as np

from .curves import ToolPath
from .lookahead import WindowChain
from .path_tables import RowSequence
from .scurve import SPARE, reach, scurve_distance, scurve_time

__all__ = ["FeedPlan", "BlockLimit", "LimitBounds", "block_limits", "joins_span", "SpanHeads", "span_profile", "profile_time",
           "scurve_time", "scurve_distance", "reach", "tolerance_feed", "junction_speed", "TANGENT_COSINE", "LOOKAHEAD_BLOCKS"]

TANGENT_COSINE = math.cos(1e-6)      # two blocks meet tangentially when their tangents differ by under 1 urad


def junction_speed(tangent_in, tangent_out, deviation: float, acceleration: float, jerk: float,
                   axis_acceleration=None, axis_jerk=None) -> float:
    """The speed at which the tool may pass the corner between a block ending along ``tangent_in`` and the
    next starting along ``tangent_out``, passing within ``deviation`` [m] of the corner (grbl's junction
    deviation, planner.c: plan_buffer_line).

    For a turn through phi, the arc tangent to both blocks whose middle lies ``deviation`` from the corner has
    radius r = deviation cos(phi / 2) / (1 - cos(phi / 2)) (grbl's sin(theta / 2) / (1 - sin(theta / 2)) with
    theta = pi - phi the angle between the blocks; the blend arc of LinuxCNC's tp.c for tolerance P has the
    same radius). Round it at v the centripetal acceleration is v^2 / r and its jerk v^3 / r^2, so v^2 <=
    A r and v^3 <= J r^2, A and J the path bounds lowered by each axis' own along the direction of the
    velocity change t_out - t_in (grbl's limit_value_by_axis_maximum). A reversal (phi = pi) or a deviation
    of 0 gives 0: an exact stop.
    """
    t0, t1 = np.asarray(tangent_in, dtype=float), np.asarray(tangent_out, dtype=float)
    change = t1 - t0
    chord = float(np.linalg.norm(change))                   # |t_out - t_in| = 2 sin(phi / 2)
    half_sine = min(0.5 * chord, 1.0)
    half_cosine = math.sqrt(1.0 - half_sine * half_sine)    # cos(phi / 2)
    if deviation <= 0.0 or half_cosine <= 1e-9:
        return 0.0
    if chord == 0.0:
        return math.inf
    u = np.abs(change) / chord
    with np.errstate(divide="ignore"):
        for limit in (axis_acceleration, axis_jerk):
            if limit is not None:
                bound = float(np.min(np.asarray(limit, dtype=float) / u))
                if limit is axis_acceleration:
                    acceleration = min(acceleration, bound)
                else:
                    jerk = min(jerk, bound)
    radius = deviation * half_cosine * (1.0 + half_cosine) / (half_sine * half_sine)   # 1 - cos = sin^2 / (1 + cos)
    return min(math.sqrt(acceleration * radius), (jerk * radius * radius) ** (1.0 / 3.0))


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
    bound: str          # one of BOUNDS


#: what can set a block's feed (:attr:`BlockLimit.bound`)
BOUNDS = ("F", "rapid", "feedrate", "axis", "centripetal", "tolerance")


class LimitTable(RowSequence):
    """A plan's :class:`BlockLimit` per block held as arrays (a long program's blocks cost 25 bytes each, not
    an object): item i is block i's limit, made on access; ``feed``, ``acceleration``, ``jerk`` the arrays."""

    def __init__(self, feed, acceleration, jerk, bound):
        self.feed, self.acceleration, self.jerk = (np.asarray(column, dtype=float) for column in (feed, acceleration, jerk))
        self._bound = np.asarray(bound, dtype=np.int8)         # index into BOUNDS

    def __len__(self) -> int:
        return len(self.feed)

    def row_item(self, i: int) -> BlockLimit:
        return BlockLimit(float(self.feed[i]), float(self.acceleration[i]), float(self.jerk[i]), BOUNDS[self._bound[i]])


def block_limits(path: ToolPath, acceleration: float, jerk: float, feedrate: float | None = None,
                 rapid_feedrate: float | None = None, normal_acceleration: float = 0.0, axis_feedrate=None,
                 axis_acceleration=None, axis_jerk=None, contour_tolerance: float = 0.0,
                 tracking_lag=None, feed_override: float = 1.0) -> list:
    """Step 1 of the module docstring: one :class:`BlockLimit` per block of ``path``; ``feed_override``
    scales every programmed feed (rapids included, as LinuxCNC's feed override with rapids scaled)."""
    bounds = LimitBounds(path.dimension, acceleration, jerk, feedrate, rapid_feedrate, normal_acceleration,
                         axis_feedrate, axis_acceleration, axis_jerk, contour_tolerance, tracking_lag, feed_override)
    return [bounds.limit(block) for block in path.blocks]


class LimitBounds:
    """The bounds of :func:`block_limits`, made once, giving each block's :class:`BlockLimit` (:meth:`limit`)
    and each junction's speed (:meth:`corner`): what the whole program's plan and a streaming plan
    (:mod:`contouring_ros.core.feed_stream`) share."""

    def __init__(self, dimension: int, acceleration: float, jerk: float, feedrate: float | None = None,
                 rapid_feedrate: float | None = None, normal_acceleration: float = 0.0, axis_feedrate=None,
                 axis_acceleration=None, axis_jerk=None, contour_tolerance: float = 0.0, tracking_lag=None,
                 feed_override: float = 1.0):
        if acceleration <= 0.0 or jerk <= 0.0:
            raise ValueError("acceleration and jerk must be positive")
        if feed_override <= 0.0:
            raise ValueError("the feed override must be positive")
        if contour_tolerance > 0.0 and tracking_lag is None:
            raise ValueError("a contour_tolerance needs the axes' tracking_lag")
        n = dimension
        self.per_axis = [np.full(n, np.inf) if v is None else np.broadcast_to(np.asarray(v, dtype=float), (n,))
                         for v in (axis_feedrate, axis_acceleration, axis_jerk)]
        self.unbounded = all(np.isposinf(limit).all() for limit in self.per_axis)
        self.acceleration, self.jerk, self.feedrate, self.rapid_feedrate = acceleration, jerk, feedrate, rapid_feedrate
        self.normal_acceleration, self.feed_override = normal_acceleration, feed_override
        self.axis_acceleration, self.axis_jerk = axis_acceleration, axis_jerk
        self.contour_tolerance = contour_tolerance
        self.lags = np.broadcast_to(np.asarray(tracking_lag, dtype=float), (n,)) if contour_tolerance > 0.0 else None
        # a straight block's limit where no bound depends on its direction: its kind and feed alone set it,
        # so the blocks that share them share one BlockLimit (a long program's lines: one)
        self._straight = {} if self.unbounded and contour_tolerance <= 0.0 else None

    def limit(self, block) -> BlockLimit:
        """Step 1 of the module docstring for one block (a :class:`~contouring_ros.core.curves.PathBlock`)."""
        if self._straight is not None and block.curvature == 0.0:
            key = (block.kind, block.feed)
            known = self._straight.get(key)
            if known is None:
                known = self._straight[key] = self._limit(block)
            return known
        return self._limit(block)

    def _limit(self, block) -> BlockLimit:
        feed_override = self.feed_override
        if block.kind == "rapid":
            if not self.rapid_feedrate:
                raise ValueError(f"line {block.line}: a rapid move (G0) needs the schedule's rapid_feedrate")
            feed, bound = self.rapid_feedrate * feed_override, "rapid"
        elif block.feed is not None:
            feed, bound = block.feed * feed_override, "F"
        elif self.feedrate:
            feed, bound = self.feedrate * feed_override, "feedrate"
        else:
            raise ValueError(f"line {block.line}: no feed rate (an F word, or the schedule's feedrate)")
        a, j = self.acceleration, self.jerk
        if self.unbounded:          # no per-axis bounds: each is infinite in every direction
            axis_v = axis_a = axis_j = math.inf
        elif block.curvature == 0.0:
            u = np.abs(block.tangent_in)
            with np.errstate(divide="ignore"):
                axis_v, axis_a, axis_j = (float(np.min(limit / u)) for limit in self.per_axis)
        else:       # the tangent turns: the tightest axis bounds every direction
            axis_v, axis_a, axis_j = (float(np.min(limit)) for limit in self.per_axis)
        a, j = min(a, axis_a), min(j, axis_j)
        if axis_v < feed:
            feed, bound = axis_v, "axis"
        if block.curvature > 0.0:
            centripetal = self.centripetal(block.curvature, a, j)
            if centripetal < feed:
                feed, bound = centripetal, "centripetal"
        if self.contour_tolerance > 0.0:
            capped = tolerance_feed(self.contour_tolerance, self.lags, block.tangent_in, block.curvature)
            if capped < feed:
                feed, bound = capped, "tolerance"
        return BlockLimit(feed, a, j, bound)

    def centripetal(self, kappa: float, acceleration: float, jerk: float) -> float:
        """The feed on an arc of curvature ``kappa`` within v^2 kappa <= A_n and v^3 kappa^2 <= J."""
        return min(math.sqrt((self.normal_acceleration or acceleration) / kappa), (jerk / kappa**2) ** (1.0 / 3.0))

    def chunk_limits(self, chunk):
        """Step 1 for a :class:`~contouring_ros.core.line_runs.StretchChunk` (its lines and blend arcs at one
        programmed feed): (feed, acceleration, jerk) lists, one value a row, each :meth:`limit`'s; None where a
        bound depends on a line's direction (axis bounds, a contour tolerance: :meth:`limit` row by row)."""
        if self._straight is None:
            return None
        line = self.limit(_Stretch("line", chunk.feed, 0.0, int(chunk.lines[0])))
        a, j = line.acceleration, line.jerk
        feed = chunk.feed * self.feed_override
        feeds = [line.feed] * len(chunk)
        for k, kappa in zip(np.flatnonzero(chunk.kind).tolist(), chunk.curvature[chunk.kind == 1].tolist()):
            feeds[k] = min(feed, self.centripetal(kappa, a, j))
        return feeds, [a] * len(chunk), [j] * len(chunk)

    def corner(self, before, after, limit_before: BlockLimit, limit_after: BlockLimit) -> float:
        """Step 2 of the module docstring: the speed limit where block ``before`` meets ``after`` (0 before a
        dwell)."""
        if before.dwell > 0.0:
            return 0.0
        if float(np.dot(before.tangent_out, after.tangent_in)) >= TANGENT_COSINE:
            return min(limit_before.feed, limit_after.feed)
        return min(limit_before.feed, limit_after.feed, junction_speed(
            before.tangent_out, after.tangent_in, before.deviation,
            min(limit_before.acceleration, limit_after.acceleration), min(limit_before.jerk, limit_after.jerk),
            self.axis_acceleration, self.axis_jerk))


@dataclass(frozen=True)
class _Stretch:
    """What :meth:`LimitBounds.limit` reads of a straight stretch."""

    kind: str
    feed: float | None
    curvature: float
    line: int


#: a block that could not rise more than this fraction above a span's feed within its own length runs on in
#: that span though its own feed is higher (:func:`joins_span`) ...
SHORT_BLOCK_GAIN = 0.01

#: ... while the span is shorter than a jerk-limited rise of this fraction above its feed would take
SHORT_RUN_GAIN = 0.1


def joins_span(limit: BlockLimit, head: BlockLimit, corner: float, hold: float, length: float,
               into: float) -> bool:
    """Whether a block runs on in the span before it (step 3), one profile bounded by the span's first
    block's feed ``head.feed``: where nothing holds between them, the bounds along the path are the same and
    the junction allows the span's feed (``corner``), a block of the span's feed; and a block whose own feed
    is higher but which is too short to use it (a jerk-limited rise from the span's feed within its
    ``length`` gains at most :data:`SHORT_BLOCK_GAIN`: the chords and micron-long blend arcs of a CAM
    program's rounded coordinates, each at a feed of its own), while the span, ``into`` its start at the
    block's, stays shorter than a rise by :data:`SHORT_RUN_GAIN` takes. As spans of their own, such blocks'
    profiles would each start and end at zero acceleration and the feed could barely change over them; as
    one span without end, a span's feed would hold the lowest block's all the way."""
    if hold != 0.0 or limit.acceleration != head.acceleration or limit.jerk != head.jerk or corner < head.feed:
        return False
    if limit.feed == head.feed:
        return True
    v, a, j = head.feed, head.acceleration, head.jerk
    return (limit.feed > v and reach(v, length, limit.feed, a, j) <= (1.0 + SHORT_BLOCK_GAIN) * v and
            into + length <= scurve_distance(v, (1.0 + SHORT_RUN_GAIN) * v, a, j))


class SpanHeads:
    """Step 3's spans as the blocks come, for the whole program's plan and the stream alike: the feed of the
    span under way (its first block's, kept across a split the look-ahead makes) and where that span began.
    """

    def __init__(self, limit: BlockLimit, start: float):
        self.head, self.start = limit, start

    @property
    def feed(self) -> float:
        return self.head.feed

    def next(self, limit: BlockLimit, start: float, length: float, corner: float, hold: float, split: bool) -> tuple:
        """Whether the block at arc length ``start`` of ``length`` (its ``limit``, the ``corner`` speed and
        ``hold`` where it begins) starts a span (:func:`joins_span`, or ``split``: the window's), and the corner
        speed, lowered where a span ends to that span's feed (no span leaves above its own feed)."""
        joins = joins_span(limit, self.head, corner, hold, length, start - self.start)
        if joins and not split:
            return False, corner
        corner = min(corner, self.head.feed)
        if not joins:
            self.head, self.start = limit, start
        return True, corner


class _PathFrom:
    """The blocks of a tool path from arc length ``theta`` on (the block holding it cut there, its tangent
    taken at theta), in the path's own arc length: what :meth:`FeedPlan.rest_of_path` plans."""

    def __init__(self, path, theta: float):
        self.path, self.dimension, self.dwell = path, path.dimension, 0.0
        self.domain = (float(theta), path.domain[1])
        blocks = []
        for block in path.blocks:
            end = block.start + block.length
            if end <= theta + 1e-12:
                continue
            if block.start < theta:
                tangent = np.asarray(path.columns(float(theta))[1], dtype=float)
                block = dataclasses.replace(block, start=float(theta), length=end - float(theta),
                                            tangent_in=tangent / np.linalg.norm(tangent))
            blocks.append(block)
        self.blocks = blocks

    def point(self, theta):
        return self.path.point(theta)


def span_profile(v0: float, v1: float, length: float, cap: float, acceleration: float, jerk: float, line: int,
                 entry=(0.0, 0.0)):
    """Step 4 of the module docstring: the time-optimal jerk-limited profile (a Ruckig ``Trajectory`` of one
    degree of freedom, the distance along the span) over a span of ``length`` from speed v0 to v1 at zero
    acceleration, within ``cap``, ``acceleration`` and ``jerk``; ``entry``: the state (feed, its rate) of a
    plan entered while moving (its acceleration is the profile's start; v0 is its feed). ValueError naming the
    span's first ``line`` where no profile exists or one would reverse along the path."""
    from ruckig import InputParameter, Result, Ruckig, RuckigError, Trajectory
    inp = InputParameter(1)
    inp.current_position, inp.current_velocity = [0.0], [v0]
    inp.current_acceleration = [entry[1]]
    if entry != (0.0, 0.0):
        # from a moving state the way down to the span's feed limit must not undershoot into reverse (a
        # jerk-limited brake from F to 10 % of it would otherwise overshoot below zero and come back)
        inp.min_velocity = [0.0]
    inp.target_position, inp.target_velocity, inp.target_acceleration = [length], [v1], [0.0]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [cap], [acceleration], [jerk]
    trajectory = Trajectory(1)
    try:
        result = Ruckig(1).calculate(inp, trajectory)
    except RuckigError as error:          # no profile from this entry state (a feed override)
        reason = next((text.strip() for text in str(error).splitlines() if text.strip()), "no reason given")
        raise ValueError(f"line {line}: no jerk-limited profile for this block ({reason})") from None
    if result not in (Result.Working, Result.Finished):
        raise ValueError(f"line {line}: no jerk-limited profile for this block ({result})")
    extrema = trajectory.position_extrema[0]
    if extrema.min < -1e-12 or extrema.max > length * (1.0 + 1e-9) + 1e-12:
        raise ValueError(f"line {line}: the planned profile would reverse along the path")
    return trajectory


def profile_time(trajectory, distance: float) -> float:
    """When a span's profile (:func:`span_profile`) has covered ``distance`` (bisection: the position rises
    monotonically along it)."""
    lo, hi = 0.0, trajectory.duration
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if trajectory.at_time(mid)[0][0] < distance:
            lo = mid
        else:
            hi = mid
    return hi


#: blocks the feed plan looks ahead by default (a block of the tool path: a program's block or a blend arc),
#: within the range controls keep (LinuxCNC 2000 segments, TwinCAT 120-500 blocks, Heidenhain up to 5000)
LOOKAHEAD_BLOCKS = 1000

#: the trajectories of this many spans are kept once planned (the latest ones asked for)
CACHED_SPANS = 8


class FeedPlan:
    """theta(t) along a tool path: the look-ahead, jerk-limited feed plan of the module docstring.

    Parameters
    ----------
    path : ToolPath
    acceleration, jerk : float
        Bounds along the path [m/s^2, m/s^3] (and the centripetal bounds on arcs and at junctions).
    feedrate : float or None
        Feed [m/s] of blocks the program gives no F (None: every feed block must have one).
    rapid_feedrate : float or None
        Feed of G0 blocks [m/s].
    normal_acceleration : float
        Centripetal acceleration bound on arcs [m/s^2] (0: ``acceleration``).
    axis_feedrate, axis_acceleration, axis_jerk : sequence or None
        Per-axis bounds (one value per axis).
    contour_tolerance : float
        [m] 0: none; else the contour-tolerance planner lowers each block's feed to
        :func:`tolerance_feed` with the axes' ``tracking_lag`` [s] (one value, or one per axis).
    dwell : float
        [s] Hold at each exact stop between blocks (a fixed settling time; the in-position check waits for
        the axes instead, :class:`~contouring_ros.core.interpolation.InPositionClock`).
    feed_override : float
        Scales every programmed feed (1: 100 %).
    lookahead_blocks : int
        Blocks the planner sees ahead (step 3 of the module docstring); 0: the whole program.
    entry : (float, float)
        The feed [m/s] and its rate [m/s^2] at the path's start: (0, 0) from rest; else a plan made while the
        tool moves (:meth:`rest_of_path`, a feed override's re-plan). The first span's profile starts from
        that state (Ruckig first brings a feed above the span's limit down within the acceleration and jerk
        bounds); ValueError where it cannot reach the first span's end without reversing.

    Attributes
    ----------
    limits : list of BlockLimit
    junctions : ndarray
        Planned speed at each block boundary (n_blocks + 1 values).
    block_times : ndarray
        Start time of each block (of the hold before it, where there is one), then the duration.
    stops : ndarray, shape (k, 2)
        Each exact stop between blocks: the time the feed reaches 0 there and the arc length of the corner.
    """

    #: runs on a batch of times (:mod:`contouring_ros.core.batch`) when every experiment of the batch has the
    #: same plan (its spans' trajectories and the tables follow from the shared limits, spans and times)
    batchable = True
    batch_shared = ("limits", "_span", "_span_times", "_block_first", "stops", "_starts", "_feed")
    batch_kept = ("_cached", "_table", "_times")

    def __init__(self, path: ToolPath, acceleration: float, jerk: float, feedrate: float | None = None,
                 rapid_feedrate: float | None = None, normal_acceleration: float = 0.0, axis_feedrate=None,
                 axis_acceleration=None, axis_jerk=None, contour_tolerance: float = 0.0, tracking_lag=None,
                 dwell: float = 0.0, feed_override: float = 1.0, lookahead_blocks: int = 0, entry=(0.0, 0.0)):
        self.curve = path
        self._arguments = dict(acceleration=acceleration, jerk=jerk, feedrate=feedrate, rapid_feedrate=rapid_feedrate,
                               normal_acceleration=normal_acceleration, axis_feedrate=axis_feedrate,
                               axis_acceleration=axis_acceleration, axis_jerk=axis_jerk,
                               contour_tolerance=contour_tolerance, tracking_lag=tracking_lag, dwell=dwell,
                               feed_override=feed_override, lookahead_blocks=lookahead_blocks)
        self.contour_tolerance = float(contour_tolerance)
        self.feed_override = float(feed_override)
        self.theta_start, self.theta_end = path.domain
        blocks = path.blocks
        bounds = LimitBounds(path.dimension, acceleration, jerk, feedrate, rapid_feedrate, normal_acceleration,
                             axis_feedrate, axis_acceleration, axis_jerk, contour_tolerance, tracking_lag,
                             feed_override)
        m = len(blocks)
        self.entry = (float(entry[0]), float(entry[1]))
        corner = np.zeros(m + 1)                 # speed limit at each block boundary
        hold = np.zeros(m + 1)                   # [s] held at each boundary before the next block
        hold[0] = getattr(path, "dwell", 0.0)
        starts, lengths = np.empty(m + 1), np.empty(m)
        starts[m] = self.theta_end
        columns = (array("d"), array("d"), array("d"), array("b"))          # the limits' (LimitTable)
        before, limit_before = None, None
        for i, block in enumerate(blocks):       # each block made once (a long path holds them as rows)
            limit = bounds.limit(block)
            for column, value in zip(columns, (limit.feed, limit.acceleration, limit.jerk, BOUNDS.index(limit.bound))):
                column.append(value)
            starts[i], lengths[i] = block.start, block.length
            if before is not None:
                hold[i] = before.dwell
                corner[i] = bounds.corner(before, block, limit_before, limit)
                if corner[i] == 0.0:
                    hold[i] += float(dwell)
            before, limit_before = block, limit
        hold[m] = before.dwell
        self.limits = LimitTable(*columns)
        feed, acc, jer = self.limits.feed, self.limits.acceleration, self.limits.jerk
        corner[0] = min(self.entry[0], feed[0])
        window = int(lookahead_blocks) if 0 < lookahead_blocks < m else 0
        split_at = set()
        if window:            # spans of at most half the window: at least half a window is seen beyond each
            splits = np.arange(0, m, max(1, window // 2))
            if self.entry[0] > feed[0]:
                # entered above the first block's feed (an override lowered it): the first span runs on over
                # the blocks the way down covers (twice the distance of a jerk-limited slow-down from the
                # speed the entry's acceleration still brings), so that it has the room to come down
                v_peak = self.entry[0] + max(self.entry[1], 0.0) ** 2 / (2.0 * jer[0])
                down = v_peak * max(self.entry[1], 0.0) / jer[0] + scurve_distance(feed[0], v_peak, acc[0], jer[0])
                splits = splits[(splits == 0) | (starts[splits] - starts[0] > 2.0 * down)]
            split_at = set(splits.tolist())
        spans, first, caps = SpanHeads(self.limits[0], float(starts[0])), [0], [feed[0]]
        for b in range(1, m):
            begins, corner[b] = spans.next(self.limits[b], float(starts[b]), float(lengths[b]), float(corner[b]),
                                           float(hold[b]), b in split_at)
            if begins:
                first.append(b)
                caps.append(spans.feed)
        first = np.array(first)
        span_start = starts[first]
        span_length = np.append(span_start[1:], self.theta_end) - span_start
        cap, span_acc, span_jerk = np.array(caps), acc[first], jer[first]
        v = corner[np.append(first, m)]
        k = len(first)
        room = span_length * (1.0 - SPARE)
        if window:
            self._windowed(v, first, starts, span_start, room, span_acc, span_jerk, window)
        else:
            for i in range(k):                   # forward: what span i can reach from its entry speed
                v[i + 1] = min(v[i + 1], reach(v[i], room[i], max(v[i + 1], v[i]), span_acc[i], span_jerk[i]))
            for i in range(k - 1, -1, -1):       # backward: what it can brake to its exit speed from
                v[i] = min(v[i], reach(v[i + 1], room[i], max(v[i], v[i + 1]), span_acc[i], span_jerk[i]))
        v[0] = self.entry[0]                     # the first span's profile starts from the entry state
        self._span = (first, span_start, span_length, cap, span_acc, span_jerk, v, hold[np.append(first, m)])
        durations = np.array([self._profile(i).duration for i in range(k)])
        span_hold = hold[first]
        # time at which the hold before span i begins, then the end of the last span
        self._span_times = np.concatenate([[0.0], np.cumsum(span_hold + durations)])
        self.duration = float(self._span_times[-1] + hold[m])
        self._block_first = first
        interior = np.flatnonzero(v[1:k] == 0.0) + 1
        self.stops = np.column_stack([self._span_times[interior], span_start[interior]]) if interior.size \
            else np.zeros((0, 2))
        self._starts = starts[:-1]
        self._feed = feed
        self._table = None
        self._times = None

    @staticmethod
    def _windowed(v, first, starts, span_start, room, acc, jerk, window: int) -> None:
        """Step 3's passes as a control with a look-ahead of ``window`` blocks makes them (in place on the
        boundary speeds ``v``): span i's exit speed is fixed when its entry is, seeing only the blocks
        first[i] .. first[i] + window - 1, the last of them taken to end in a stop (what is beyond is not
        known yet), by :class:`~contouring_ros.core.lookahead.WindowChain`. So each span can still brake to a
        stop within what was seen, and the plan is never shorter than the whole program's."""
        k, m = len(first), len(starts) - 1
        speed, span_start, room = v.tolist(), span_start.tolist(), room.tolist()
        acc, jerk = acc.tolist(), jerk.tolist()
        ends = np.minimum(first + window, m)                  # the first block beyond each span's window
        lasts = np.searchsorted(first, ends, side="left").tolist()
        horizons = starts[ends].tolist()
        chain, added = WindowChain(), 0
        for i in range(k):
            last = lasts[i] if ends[i] < m else k
            for j in range(added, last):
                chain.add(j, speed[j], span_start[j], acc[j], jerk[j])
            added = max(added, last)
            stop = speed[k] if last == k else 0.0             # the program's end in sight, or the window's
            speed[i + 1] = chain.exit_speed(i, speed[i], speed[i + 1], room[i], last, stop, horizons[i])
        v[:] = speed

    def _profile(self, i: int):
        """Span i's Ruckig trajectory (the last few asked for are kept: the reference walks the spans in order,
        a batch's members waiting at exact stops of their own a few spans apart)."""
        cached = vars(self).setdefault("_cached", {})
        if i in cached:
            return cached[i]
        _, start, length, cap, acc, jerk, v, _ = self._span
        trajectory = span_profile(float(v[i]), float(v[i + 1]), float(length[i]), float(cap[i]), float(acc[i]),
                                  float(jerk[i]), self.curve.blocks[int(self._span[0][i])].line,
                                  self.entry if i == 0 else (0.0, 0.0))
        if len(cached) >= CACHED_SPANS:
            del cached[next(iter(cached))]
        cached[i] = trajectory
        return trajectory

    def __deepcopy__(self, memo):
        """A deep copy sharing the last planned trajectory (read only once planned; Ruckig's cannot be copied)."""
        out = copy.copy(self)
        memo[id(self)] = out
        for name, value in vars(self).items():
            setattr(out, name, dict(value) if name == "_cached" else copy.deepcopy(value, memo))
        return out

    def _one(self, t: float):
        if t >= self.duration:
            return self.theta_end, 0.0, 0.0
        t = max(t, 0.0)
        times = self._span_times
        _, start, length, _, _, _, _, hold = self._span
        i = int(np.searchsorted(times, t, side="right")) - 1
        if i >= len(start):                      # the hold after the last block
            return self.theta_end, 0.0, 0.0
        into = t - times[i] - hold[i]
        if into <= 0.0:                          # holding before span i (or at the entry state)
            return (float(start[i]), *self.entry) if i == 0 and hold[0] == 0.0 else (float(start[i]), 0.0, 0.0)
        trajectory = self._profile(i)
        if into >= trajectory.duration:
            return float(start[i] + length[i]), float(self._span[6][i + 1]), 0.0
        p, v, a = trajectory.at_time(into)
        return float(start[i]) + min(max(p[0], 0.0), float(length[i])), v[0], a[0]

    def __call__(self, t):
        """theta (= arc length), theta_dot (feed), theta_ddot at time(s) t."""
        if np.ndim(t) == 0:
            return self._one(float(t))
        times, where = np.unique(np.ravel(t), return_inverse=True)      # a batch's steps share one time
        rows = np.array([self._one(float(x)) for x in times])[where].reshape(np.shape(t) + (3,))
        return rows[..., 0], rows[..., 1], rows[..., 2]

    def time_at(self, theta: float) -> float:
        """When the feed plan reaches arc length ``theta`` (the start of the hold there, if any)."""
        first, start, length, _, _, _, _, hold = self._span
        i = int(np.clip(np.searchsorted(start, theta, side="right") - 1, 0, len(start) - 1))
        into = theta - start[i]
        if into <= 0.0:
            return float(self._span_times[i])
        return float(self._span_times[i] + hold[i] + profile_time(self._profile(i), into))

    @property
    def block_times(self) -> np.ndarray:
        """Start time of each block (of the hold before it), then the duration."""
        if self._times is None:
            self._times = np.array([self.time_at(float(s)) for s in self._starts] + [self.duration])
        return self._times

    @property
    def junctions(self) -> np.ndarray:
        """Planned speed at each block boundary: the span boundaries' speeds, within a span the profile's."""
        first, *_, v, _ = self._span
        out = np.array([self._one(float(t))[1] for t in self.block_times])
        out[first] = v[:-1]
        out[-1] = v[-1]
        return out

    def rest_of_path(self, theta: float, feed_override: float | None = None, entry=(0.0, 0.0)) -> "FeedPlan | None":
        """The same plan (bounds, feeds, look-ahead) of the path from arc length theta on, from the ``entry``
        state there (feed, its rate; rest by default), with another ``feed_override`` where given: what a
        control plans when it resumes after a feed hold, or when the feed override changes while it moves;
        None where nothing is left. ValueError where no profile leaves the entry state within the bounds."""
        path = _PathFrom(getattr(self.curve, "path", self.curve), theta)      # the whole path, after a resume too
        arguments = self._arguments if feed_override is None else {**self._arguments, "feed_override": feed_override}
        return FeedPlan(path, **arguments, entry=entry) if path.blocks else None

    def bounds_at(self, theta: float) -> tuple:
        """(acceleration, jerk) bounds along the path of the block at arc length theta."""
        i = int(np.clip(np.searchsorted(self._starts, theta, side="right") - 1, 0, len(self.limits) - 1))
        return self.limits[i].acceleration, self.limits[i].jerk

    def feed_limit_at(self, theta):
        """The feed limit of the block at arc length(s) theta."""
        i = np.clip(np.searchsorted(self._starts, theta, side="right") - 1, 0, len(self.limits) - 1)
        return self._feed[i]

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
