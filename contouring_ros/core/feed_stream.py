"""A streaming feed plan: a part program read, made a tool path and planned while it runs, over a look-ahead
window of blocks, as a CNC control's block queue does (LinuxCNC's trajectory planner keeps 2000 segments,
TwinCAT 120 to 500 blocks, Heidenhain up to 5000).

The pipeline is lazy from end to end: the program's lines (any iterable: a file read line by line) become
blocks (:class:`~contouring_ros.core.gcode.ProgramReader`, G64 Q merged by
:func:`~contouring_ros.core.gcode.merge_collinear`; runs of plain G1 lines as
:class:`~contouring_ros.core.gcode.LineRun` arrays), the blocks tool-path stretches with their corner blends
(:meth:`~contouring_ros.core.curves.ToolPath.stream`; a run's as one
:class:`~contouring_ros.core.line_runs.StretchChunk`), and :class:`StreamingPlan` plans the stretches as
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

import numpy as np

from .curves import ToolPath, segment_columns
from .feed_planning import (LOOKAHEAD_BLOCKS, TANGENT_COSINE, BlockLimit, LimitBounds, SpanHeads, profile_time,
                            span_profile)
from .gcode import ProgramError, ProgramReader, merge_collinear
from .line_runs import StretchChunk
from .lookahead import WindowChain
from .scurve import SPARE

__all__ = ["PlannedSpan", "StreamingPlan", "stream_program", "RUN_BLOCKS"]

#: a run of plain G1 lines is planned as arrays of at most this many blocks
RUN_BLOCKS = 256

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
    stretches : sequence
        Its ((segment, plain), :class:`~contouring_ros.core.curves.PathBlock`) pairs, for the reference (made
        as they are asked for); ``starts`` where each begins [m].
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
    stretches: object
    starts: list

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
        self.blocks_read = 0          # stretches taken into the window so far
        self._split = max(1, self.window // 2)        # a span begins at least every W / 2 stretches
        # the window's stretches from its first on, a column each: start, length, the corner speed where it
        # begins, the hold there, its span's feed, its acceleration and jerk bounds, source line, dwell, and
        # its source (a (pair, PathBlock) or (StretchChunk, row)); where the spans begin; stretches of a chunk
        # not yet taken (the same columns and each row's number where it begins a span, -1 elsewhere)
        self._columns = tuple([] for _ in range(10))
        self._firsts = deque()
        self._pending, self._pending_at = None, 0
        self._previous, self._numbered = None, 0        # the last stretch numbered (PathBlock, limit), how many
        self.end_hold = 0.0           # [s] the last stretch's dwell (known once the stream has ended)

    def _read(self, need: int) -> bool:
        """Take stretches into the window until ``need`` are in (its columns, from ``self._base`` on); False
        at the stream's end."""
        while self.blocks_read < need:
            if self._pending is None:
                try:
                    item = next(self._source)
                except StopIteration:
                    return False
                if item.__class__ is StretchChunk:
                    self._add_chunk(item)
                else:
                    self._add(item)
                continue
            at, rows = self._pending_at, self._pending
            take = min(len(rows[0]) - at, need - self.blocks_read)
            for column, values in zip(self._columns, rows):
                column.extend(values[at:at + take])
            self._firsts.extend(n for n in rows[-1][at:at + take] if n >= 0)
            self._pending_at = at + take
            self.blocks_read += take
            if self._pending_at == len(rows[0]):
                self._pending = None
        return True

    def _add(self, pair, block=None) -> None:
        """One stretch ((segment, plain), PathBlock) into the window: its limit, the corner where it begins,
        the hold there, whether it starts a span and that span's feed."""
        if block is None:
            pair, block = pair
        limit = self.bounds.limit(block)
        b = self._numbered
        if self._previous is None:
            dwell = self._first_dwell
            corner, hold, starts = 0.0, float(dwell() if callable(dwell) else dwell), True
            self._spans = SpanHeads(limit, block.start)
        else:
            before, before_limit = self._previous
            corner = self.bounds.corner(before, block, before_limit, limit)
            hold = before.dwell + (self.dwell if corner == 0.0 else 0.0)
            starts, corner = self._spans.next(limit, block.start, block.length, corner, hold, b % self._split == 0)
        for column, value in zip(self._columns, (block.start, block.length, corner, hold, self._spans.feed,
                                                 limit.acceleration, limit.jerk, block.line, block.dwell,
                                                 (pair, block))):
            column.append(value)
        if starts:
            self._firsts.append(b)
        self._previous = (block, limit)
        self._numbered = b + 1
        self.blocks_read += 1

    def _add_chunk(self, chunk) -> None:
        """A :class:`~contouring_ros.core.line_runs.StretchChunk`'s stretches, as :meth:`_add` takes them one
        at a time (the same numbers: its first row and any corner that is not tangential are :meth:`_add`'s
        own arithmetic), held as pending rows that :meth:`_read` moves into the window as it needs them."""
        limits = self.bounds.chunk_limits(chunk)
        if limits is None:                     # bounds that depend on direction: row by row
            for k in range(len(chunk)):
                self._add(*chunk.pair(k))
            return
        feeds, accelerations, jerks = limits
        first = len(self._columns[0])
        self._add(*chunk.pair(0))              # the corner from the stretch before, and a first span
        row0 = [column.pop() for column in self._columns]
        if self._firsts and self._firsts[-1] == self._numbered - 1:
            self._firsts.pop()
            first_starts = True
        else:
            first_starts = False
        self.blocks_read -= 1
        assert len(self._columns[0]) == first
        m = len(chunk)
        out, into = chunk.tangent_out[:-1], chunk.tangent_in[1:]
        dots = (out * into).sum(axis=1) if out.shape[1] != 2 else out[:, 0] * into[:, 0] + out[:, 1] * into[:, 1]
        near = np.flatnonzero(np.abs(dots - TANGENT_COSINE) < 1e-9)
        for k in near.tolist():                # on the threshold: the scalar path's dot product decides
            dots[k] = float(np.dot(out[k], into[k]))
        tangential = (dots >= TANGENT_COSINE).tolist()
        corners = [0.0] * m
        rows = None
        for k in range(1, m):
            if tangential[k - 1]:
                corners[k] = min(feeds[k - 1], feeds[k])
            else:
                rows = rows or {}
                before, after = chunk.pair(k - 1)[1], chunk.pair(k)[1]
                corners[k] = self.bounds.corner(before, after, BlockLimit(feeds[k - 1], accelerations[k - 1],
                                                                          jerks[k - 1], "F"),
                                                BlockLimit(feeds[k], accelerations[k], jerks[k], "F"))
        holds = [self.dwell if c == 0.0 else 0.0 for c in corners]
        starts, lengths = chunk.starts.tolist(), chunk.lengths.tolist()
        span_feed, numbers = [row0[4]] + [0.0] * (m - 1), [self._numbered - 1 if first_starts else -1]
        spans, split, b = self._spans, self._split, self._numbered
        head = spans.head
        for k in range(1, m):
            c, h, f = corners[k], holds[k], feeds[k]
            if b % split and h == 0.0 and f == head.feed and c >= head.feed and \
                    accelerations[k] == head.acceleration and jerks[k] == head.jerk:
                numbers.append(-1)             # runs on in the span under way (SpanHeads.next's quick answer)
            else:
                limit = BlockLimit(f, accelerations[k], jerks[k], "F")
                begins, corners[k] = spans.next(limit, starts[k], lengths[k], c, h, b % split == 0)
                head = spans.head
                numbers.append(b if begins else -1)
            span_feed[k] = head.feed
            b += 1
        self._numbered = b
        last = chunk.pair(m - 1)
        self._previous = (last[1], BlockLimit(feeds[-1], accelerations[-1], jerks[-1], "F"))
        sources = [row0[9]] + [(chunk, k) for k in range(1, m)]
        self._pending = ([row0[0]] + starts[1:], [row0[1]] + lengths[1:], [row0[2]] + corners[1:],
                         [row0[3]] + holds[1:], span_feed, accelerations, jerks, chunk.lines.tolist(), [0.0] * m,
                         sources, numbers)
        self._pending_at = 0

    def spans(self):
        """The planned spans in order (a generator; each is planned once the window ahead of it is read).

        Span i (its first stretch ``base``) sees stretches base .. base + W - 1 (``FeedPlan._windowed``):
        forward, the exit speed span i reaches from its entry; backward, from a stop at the window's end (at
        the path's end where that is in sight) over the spans beginning in the window
        (:class:`~contouring_ros.core.lookahead.WindowChain`)."""
        window = self.window
        start, length, corner, hold, feed, acc, jerk, line, dwell, source = self._columns
        firsts = self._firsts                     # the stretch numbers where the spans read so far begin
        chain, sighted = WindowChain(), 0         # spans handed to the chain (those beginning in a window)
        ended, base = False, 0                    # base: the number of the window's first stretch
        v_entry, t, index = 0.0, 0.0, 0
        while True:
            if not ended and not self._read(base + window + 1):         # stretches base .. base + W
                ended = True                      # the path's end is in the window
                self.end_hold = dwell[-1] if dwell else 0.0
            count = len(start)
            if not count:
                return
            end = base + (count if ended else window)            # the first stretch beyond the window
            while sighted - index < len(firsts) and firsts[sighted - index] < end:
                n = firsts[sighted - index] - base
                chain.add(sighted, corner[n], start[n], acc[n], jerk[n])
                sighted += 1
            if ended:
                horizon = start[-1] + length[-1]                 # where the window's stop is: the path's end
            else:
                horizon = start[window]                          # the start of the first stretch beyond it
            stop = firsts[1] - base if len(firsts) > 1 else count      # the stretches of span i
            if sighted > index + 1:
                exit_corner = corner[stop]
            else:
                exit_corner = 0.0 if ended else corner[window]
            span_length = (start[stop] if stop < count else horizon) - start[0]
            v_next = chain.exit_speed(index, v_entry, exit_corner, span_length * (1.0 - SPARE), sighted, 0.0,
                                      horizon)
            trajectory = span_profile(v_entry, v_next, span_length, feed[0], acc[0], jerk[0], line[0])
            yield PlannedSpan(index, base, start[0], span_length, t, hold[0], v_entry, v_next, feed[0], acc[0],
                              jerk[0], trajectory, _Stretches(source[:stop]), start[:stop])
            t = t + (hold[0] + trajectory.duration)
            for column in self._columns:
                del column[:stop]
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
            starts = span.starts
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
            yield k * sample_time, end, 0.0, 0.0, self._point(span, span.starts, end)
            k += 1

    def _point(self, span, starts, theta):
        n = min(max(bisect.bisect_right(starts, theta) - 1, 0), len(starts) - 1)
        (segment, plain), block = span.stretches[n]
        return segment_columns(segment, plain, self.dimension, theta - block.start)[0]


class _Stretches:
    """A span's stretches as ((segment, plain), PathBlock) pairs, each made when asked for from its source in
    the window (the pair itself, or a chunk and its row)."""

    def __init__(self, sources: list):
        self._sources = sources

    def __len__(self) -> int:
        return len(self._sources)

    def __getitem__(self, n: int):
        source = self._sources[n]
        return source[0].pair(source[1]) if source[0].__class__ is StretchChunk else source

    def __iter__(self):
        for n in range(len(self._sources)):
            yield self[n]


def stream_program(lines, dimension: int, start=(0.0, 0.0, 0.0), strict: bool = False,
                   blend_tolerance: float = 0.0, **plan) -> StreamingPlan:
    """The streaming plan of a part program's ``lines`` (any iterable of strings, read as the plan needs
    them), on ``dimension`` axes; ``plan``: :class:`StreamingPlan`'s bounds and look-ahead. A block that
    leaves the XY plane of a 2-axis stream is refused (:class:`~contouring_ros.core.gcode.ProgramError`)."""
    reader = ProgramReader(start, strict)

    def blocks():
        # runs of plain G1 lines read as arrays, each at most a quarter of the window (the read-ahead it adds)
        runs = min(RUN_BLOCKS, max(1, int(plan.get("lookahead_blocks", LOOKAHEAD_BLOCKS)) // 4))
        for block in merge_collinear(reader.blocks(lines, runs=runs)):
            if dimension < 3 and block.kind == "run":
                off = np.flatnonzero((block.points[:-1, 2] != 0.0) | (block.points[1:, 2] != 0.0))
                if off.size:
                    raise ProgramError(f"line {block.lines[off[0]]}: the program moves Z; the stream has "
                                       f"{dimension} axes")
            elif dimension < 3 and (block.start[2] != 0.0 or block.end[2] != 0.0 or
                                    (block.kind == "arc" and block.plane != (0, 1, 2))):
                raise ProgramError(f"line {block.line}: the program moves Z; the stream has {dimension} axes")
            yield block
    return StreamingPlan(ToolPath.stream(blocks(), dimension, blend_tolerance), dimension,
                         first_dwell=lambda: reader.first_dwell, **plan)
