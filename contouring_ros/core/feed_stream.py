"""A streaming feed plan: a part program read, made a tool path and planned while it runs, over a look-ahead
window of blocks, as a CNC control's block queue does (LinuxCNC's trajectory planner keeps 2000 segments,
TwinCAT 120 to 500 blocks, Heidenhain up to 5000).

The pipeline is lazy from end to end: the program's lines (any iterable: a file read line by line) become
blocks (:class:`~contouring_ros.core.gcode.ProgramReader`, G64 Q merged by
:func:`~contouring_ros.core.gcode.merge_collinear`), the blocks tool-path stretches with their corner blends
(:meth:`~contouring_ros.core.curves.ToolPath.stream`), and :class:`StreamingPlan` plans the stretches as
:class:`~contouring_ros.core.feed_planning.FeedPlan` does with ``lookahead_blocks`` W (its module docstring,
steps 1-4, and ``FeedPlan._windowed``): a span's exit speed is fixed when its entry is, from the W stretches
ahead of its start alone, the last taken to end in a stop. That needs nothing beyond the W + 1 stretches
ahead, so the plan holds at most those, whatever the program's length; the first span is planned, and the
first reference sample leaves, once the first W + 1 stretches are read. On a program of more than W
stretches the plan it makes is ``FeedPlan(path, lookahead_blocks=W)``'s span for span and sample for sample
(tested; on a shorter one FeedPlan plans the whole program at once, the stream still in spans of at most
W / 2): never shorter than the whole program's plan, and within every bound.
"""
from __future__ import annotations

import bisect
from collections import deque
from dataclasses import dataclass

from .curves import ToolPath, segment_columns
from .feed_planning import LOOKAHEAD_BLOCKS, LimitBounds, SpanHeads, profile_time, span_profile
from .gcode import ProgramError, ProgramReader, merge_collinear
from .lookahead import WindowChain
from .scurve import SPARE

__all__ = ["PlannedSpan", "StreamingPlan", "stream_program"]

@dataclass(frozen=True)
class PlannedSpan:
    """One planned span: consecutive stretches run by one jerk-limited profile.

    Attributes
    ----------
    index : int
        Its number from 0; ``first`` the number of its first stretch.
    start, length : float
        [m] Arc length where it begins, and its length.
    time : float
        [s] When the hold before it (``hold`` s, an exact stop's dwell or a G4) begins; its motion begins at
        ``time + hold`` and lasts ``trajectory.duration``.
    entry, exit, cap, acceleration, jerk : float
        Its boundary speeds and bounds [m/s, m/s, m/s, m/s^2, m/s^3].
    trajectory : ruckig.Trajectory
        Distance along the span against time from the end of the hold.
    stretches : tuple
        Its ((segment, plain), :class:`~contouring_ros.core.curves.PathBlock`) pairs, for the reference.
    """

    index: int
    first: int
    start: float
    length: float
    time: float
    hold: float
    entry: float
    exit: float
    cap: float
    acceleration: float
    jerk: float
    trajectory: object
    stretches: tuple

    def time_at(self, theta: float) -> float:
        """When the plan reaches arc length ``theta`` within the span (the start of its hold at its start)."""
        into = theta - self.start
        return self.time if into <= 0.0 else self.time + self.hold + profile_time(self.trajectory, into)

    @property
    def end_time(self) -> float:
        return self.time + (self.hold + self.trajectory.duration)      # as the next span's time is summed


class StreamingPlan:
    """The windowed feed plan of a stream of tool-path stretches (see the module docstring).

    Parameters
    ----------
    stretches : iterable
        ((segment, plain), PathBlock) pairs in order, as :meth:`ToolPath.stream` yields them.
    dimension : int
        The path's axes.
    acceleration, jerk, feedrate, rapid_feedrate, normal_acceleration, axis_feedrate, axis_acceleration,
    axis_jerk, contour_tolerance, tracking_lag, dwell, feed_override :
        As :class:`~contouring_ros.core.feed_planning.FeedPlan`'s.
    lookahead_blocks : int
        W >= 1: the stretches seen ahead.
    first_dwell : float or callable
        [s] G4 before the first motion (a callable: asked once the first stretch is read).
    """

    def __init__(self, stretches, dimension: int, acceleration: float, jerk: float, feedrate: float | None = None,
                 rapid_feedrate: float | None = None, normal_acceleration: float = 0.0, axis_feedrate=None,
                 axis_acceleration=None, axis_jerk=None, contour_tolerance: float = 0.0, tracking_lag=None,
                 dwell: float = 0.0, feed_override: float = 1.0, lookahead_blocks: int = LOOKAHEAD_BLOCKS,
                 first_dwell: float = 0.0):
        if int(lookahead_blocks) < 1:
            raise ValueError(f"lookahead_blocks: {lookahead_blocks} (a streaming plan sees at least 1 block ahead)")
        self.dimension = int(dimension)
        self.window = int(lookahead_blocks)
        self.bounds = LimitBounds(dimension, acceleration, jerk, feedrate, rapid_feedrate, normal_acceleration,
                                  axis_feedrate, axis_acceleration, axis_jerk, contour_tolerance, tracking_lag,
                                  feed_override)
        self.dwell, self._first_dwell = float(dwell), first_dwell
        self._source = iter(stretches)
        self.blocks_read = 0          # stretches read so far
        self.end_hold = 0.0           # [s] the last stretch's dwell (known once the stream has ended)

    def _read(self, buffer: deque, previous):
        """Read one stretch into ``buffer`` as [pair, block, limit, corner, hold, starts_span, span's feed]; False
        at the stream's end."""
        try:
            pair, block = next(self._source)
        except StopIteration:
            return False
        limit = self.bounds.limit(block)
        b = self.blocks_read
        if previous is None:
            dwell = self._first_dwell
            corner, hold, starts = 0.0, float(dwell() if callable(dwell) else dwell), True
            self._spans = SpanHeads(limit, block.start)
        else:
            _, before, before_limit, *_ = previous
            corner = self.bounds.corner(before, block, before_limit, limit)
            hold = before.dwell + (self.dwell if corner == 0.0 else 0.0)
            starts, corner = self._spans.next(limit, block.start, block.length, corner, hold, b % max(1, self.window // 2) == 0)
        buffer.append([pair, block, limit, corner, hold, starts, self._spans.feed])
        self.blocks_read = b + 1
        return True

    def spans(self):
        """The planned spans in order (a generator; each is planned once the window ahead of it is read).

        Span i (its first stretch ``base``) sees stretches base .. base + W - 1 (``FeedPlan._windowed``):
        forward, the exit speed span i reaches from its entry; backward, from a stop at the window's end (at
        the path's end where that is in sight) over the spans beginning in the window
        (:class:`~contouring_ros.core.lookahead.WindowChain`)."""
        window = self.window
        buffer, previous = deque(), None          # the stretches from the current span's first on
        firsts = deque()                          # the stretch numbers where the spans read so far begin
        chain, sighted = WindowChain(), 0         # spans handed to the chain (those beginning in a window)
        ended, base = False, 0                    # base: the number of buffer[0]
        v_entry, t, index = 0.0, 0.0, 0
        while True:
            while not ended and self.blocks_read <= base + window:         # stretches base .. base + W
                if self._read(buffer, previous):
                    previous = buffer[-1]
                    if previous[5]:
                        firsts.append(self.blocks_read - 1)
                else:
                    ended = True                  # the path's end is in the window
                    self.end_hold = buffer[-1][1].dwell if buffer else 0.0
            if not buffer:
                return
            end = base + (len(buffer) if ended else window)            # the first stretch beyond the window
            while sighted - index < len(firsts) and firsts[sighted - index] < end:
                record = buffer[firsts[sighted - index] - base]
                chain.add(sighted, record[3], record[1].start, record[2].acceleration, record[2].jerk)
                sighted += 1
            if ended:
                tail = buffer[-1][1]
                horizon = tail.start + tail.length           # where the window's stop is: the path's end
            else:
                horizon = buffer[window][1].start            # the start of the first stretch beyond it
            stop = firsts[1] - base if len(firsts) > 1 else len(buffer)      # the stretches of span i
            if sighted > index + 1:
                corner = buffer[stop][3]
            else:
                corner = 0.0 if ended else buffer[window][3]
            head = buffer[0]
            length = (buffer[stop][1].start if stop < len(buffer) else horizon) - head[1].start
            v_next = chain.exit_speed(index, v_entry, corner, length * (1.0 - SPARE), sighted, 0.0, horizon)
            stretches = tuple((buffer[n][0], buffer[n][1]) for n in range(stop))
            trajectory = span_profile(v_entry, v_next, length, head[6], head[2].acceleration, head[2].jerk,
                                      head[1].line)
            yield PlannedSpan(index, base, head[1].start, length, t, head[4], v_entry, v_next, head[6],
                              head[2].acceleration, head[2].jerk, trajectory, stretches)
            t = t + (head[4] + trajectory.duration)
            for _ in range(stop):
                buffer.popleft()
            firsts.popleft()
            base += stop
            index += 1
            v_entry = v_next

    def samples(self, sample_time: float):
        """The reference every ``sample_time`` s from t = 0 (a generator of (t, theta, theta_dot, theta_ddot,
        point) tuples, theta the arc length and point a tuple of the axes' positions), as
        :class:`~contouring_ros.core.feed_planning.FeedPlan` gives it at the same times, until the motion and
        the last hold end."""
        k, span = 0, None
        for span in self.spans():
            starts = [block.start for _, block in span.stretches]
            motion = span.time + span.hold
            while True:
                t = k * sample_time
                if t >= span.end_time:
                    break
                into = t - motion
                if into <= 0.0:
                    theta, v, a = span.start, 0.0, 0.0
                else:
                    p, vel, accel = span.trajectory.at_time(into)
                    theta, v, a = span.start + min(max(p[0], 0.0), span.length), vel[0], accel[0]
                yield t, theta, v, a, self._point(span, starts, theta)
                k += 1
        if span is None:
            return
        end = span.start + span.length
        final = span.end_time + self.end_hold
        while k * sample_time < final:
            yield k * sample_time, end, 0.0, 0.0, self._point(span, [b.start for _, b in span.stretches], end)
            k += 1

    def _point(self, span, starts, theta):
        n = min(max(bisect.bisect_right(starts, theta) - 1, 0), len(starts) - 1)
        (segment, plain), block = span.stretches[n]
        return segment_columns(segment, plain, self.dimension, theta - block.start)[0]


def stream_program(lines, dimension: int, start=(0.0, 0.0, 0.0), strict: bool = False,
                   blend_tolerance: float = 0.0, **plan) -> StreamingPlan:
    """The streaming plan of a part program's ``lines`` (any iterable of strings, read as the plan needs
    them), on ``dimension`` axes; ``plan``: :class:`StreamingPlan`'s bounds and look-ahead. A block that
    leaves the XY plane of a 2-axis stream is refused (:class:`~contouring_ros.core.gcode.ProgramError`)."""
    reader = ProgramReader(start, strict)

    def blocks():
        for block in merge_collinear(reader.blocks(lines)):
            if dimension < 3 and (block.start[2] != 0.0 or block.end[2] != 0.0 or
                                  (block.kind == "arc" and block.plane != (0, 1, 2))):
                raise ProgramError(f"line {block.line}: the program moves Z; the stream has {dimension} axes")
            yield block
    return StreamingPlan(ToolPath.stream(blocks(), dimension, blend_tolerance), dimension,
                         first_dwell=lambda: reader.first_dwell, **plan)
