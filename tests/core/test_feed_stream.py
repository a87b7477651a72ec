"""The streaming feed plan (core/feed_stream.py): the windowed whole-program plan span for span and sample for
sample, never faster than the whole program's plan block by block and within every bound, the program read
no further than the window ahead, and its refusals."""
import math
from pathlib import Path

import numpy as np
import pytest

from contouring_ros.core.curves import ToolPath
from contouring_ros.core.feed_planning import FeedPlan
from contouring_ros.core.feed_stream import stream_program
from contouring_ros.core.gcode import ProgramError, parse_program
from contouring_ros.studies.paper import CONFIG_DIR

BOUNDS = dict(acceleration=1.0, jerk=10.0, rapid_feedrate=0.05)
PART = (Path(CONFIG_DIR) / "parts" / "example_part.ngc").read_text()


def chord_circle(chords: int, radius_mm: float = 10.0) -> str:
    """A circle of G1 chords at F1200 under G64 P0.001, reached by a G0 from the origin."""
    rows = [f"G21 G90 G0 X{radius_mm} Y0", "G64 P0.001"]
    rows += [f"G1 X{radius_mm * math.cos(2 * math.pi * i / chords):.6f} "
             f"Y{radius_mm * math.sin(2 * math.pi * i / chords):.6f}" + (" F1200" if i == 1 else "")
             for i in range(1, chords + 1)]
    return "\n".join(rows) + "\n"


def cam_spiral(chords: int, decimals: int = 4) -> str:
    """A spiral of 5 um G1 chords at F1200 under G64 P0.001, its coordinates rounded as a CAM system writes
    them: the rounding turns each chord by up to tens of milliradians, so every chord is a span of its own,
    at a junction speed of its own."""
    rows, radius, angle = ["G21 G90 G17 G64 P0.001", "G1 X10 Y0 F1200"], 10.0, 0.0
    for _ in range(chords):
        angle, radius = angle + 0.005 / radius, radius + 1e-6
        rows.append(f"X{radius * math.cos(angle):.{decimals}f} Y{radius * math.sin(angle):.{decimals}f}")
    return "\n".join(rows) + "\n"


#: path control of every kind: G64 P with Q merging, a dwell, G9, an arc, a rapid, exact stop, feed changes
MIXED = """%
G21 G90 G64 P0.01 Q0.005
G1 X1 Y0 F600
X2 Y0.001
X3 Y0
G4 P0.2
G1 X3 Y2 F1200
G9 X1 Y3
G2 X0 Y2 R1.5 F900
G0 X0 Y0
G64 P0.005
G1 X0.5 Y0.2 F300
X1 Y0
X1.5 Y0.2 F450
G61 X2 Y0
G3 X2 Y1 I0 J0.5
M30
%
"""


def stream(text, dimension, window, **bounds):
    return stream_program(iter(text.splitlines()), dimension, lookahead_blocks=window, **{**BOUNDS, **bounds})


@pytest.mark.parametrize("text, dimension, window", [(chord_circle(720), 2, 50), (chord_circle(720), 2, 7),
                                                     (PART, 3, 2), (PART, 3, 4), (MIXED, 2, 3), (MIXED, 2, 6),
                                                     (cam_spiral(600), 2, 50), (cam_spiral(600), 2, 20)])
def test_the_stream_is_the_windowed_plan_span_for_span_and_sample_for_sample(text, dimension, window):
    path = ToolPath.from_program(parse_program(text))
    assert window < len(path.blocks)              # FeedPlan windows only a shorter look-ahead than the path
    windowed = FeedPlan(path, lookahead_blocks=window, **BOUNDS)
    plan = stream(text, dimension, window)
    spans = list(plan.spans())
    first, start, length, cap, acc, jerk, v, hold = windowed._span
    assert [s.first for s in spans] == list(first)
    assert [s.start for s in spans] == list(start) and [s.length for s in spans] == list(length)
    assert [s.entry for s in spans] + [spans[-1].exit] == list(v)
    assert [s.hold for s in spans] == list(hold[:-1])
    rows = list(stream(text, dimension, window).samples(1e-3))
    t = np.array([r[0] for r in rows])
    assert len(rows) == math.floor(windowed.duration / 1e-3) + 1           # every step until the plan's end
    theta, feed, rate = windowed(t)
    assert np.array_equal(theta, [r[1] for r in rows]) and np.array_equal(feed, [r[2] for r in rows])
    assert np.array_equal(rate, [r[3] for r in rows])
    assert np.array_equal(np.array([path.point(x) for x in theta]), np.array([r[4] for r in rows]))


@pytest.mark.parametrize("text, dimension, windows, slower", [(chord_circle(720), 2, (4, 20, 100, 400, 2000), True),
                                                              (PART, 3, (2, 4, 8), False),
                                                              (MIXED, 2, (2, 5, 40), None),
                                                              (cam_spiral(600), 2, (20, 50, 200), True)])
def test_the_window_is_never_faster_than_the_whole_plan_block_by_block_and_holds_every_bound(text, dimension,
                                                                                            windows, slower):
    """The chord circle's short windows are slower (they brake for a stop they cannot see past); the example
    part stops at every corner (G61), so no window changes its plan. On the rounded spiral a window that sees
    further can allow a lower speed at a boundary than the one before (a jerk-limited slow-down is not
    monotone in its distance): the feed keeps to the plan it was fixed from, never reversing."""
    path = ToolPath.from_program(parse_program(text))
    whole = FeedPlan(path, **BOUNDS)
    whole_times = np.diff(whole.block_times)
    lengths = np.array([b.length for b in path.blocks])
    limits = np.array([limit.feed for limit in whole.limits])
    durations = []
    for window in windows:
        plan = stream(text, dimension, window)
        starts, ends = [], []
        for span in plan.spans():
            starts += [span.time_at(block.start) for _, block in span.stretches]
            ends.append(span.end_time)
        times = np.diff(starts + [ends[-1] + plan.end_hold])
        durations.append(ends[-1] + plan.end_hold)
        assert (times >= whole_times - 1e-12).all()                       # each block's time at least the whole's
        assert (lengths / times <= lengths / whole_times * (1 + 1e-9)).all()   # its mean feed at most the whole's
        rows = np.array([r[:4] for r in stream(text, dimension, window).samples(1e-4)])
        theta, feed, rate = rows[:, 1], rows[:, 2], rows[:, 3]
        block = np.clip(np.searchsorted([b.start for b in path.blocks], theta, side="right") - 1, 0, None)
        assert (feed <= limits[block] * (1 + 1e-9) + 1e-12).all() and (feed >= -1e-12).all()
        assert np.abs(rate).max() <= BOUNDS["acceleration"] * (1 + 1e-9)
        assert np.abs(np.diff(rate)).max() / 1e-4 <= BOUNDS["jerk"] * (1 + 1e-6)
        assert np.all(np.diff(theta) >= 0.0)
    assert durations[-1] >= whole.duration * (1 - 1e-12)
    if slower is not None:
        assert (durations[0] > durations[-1] * 1.5) == slower


def test_the_program_is_read_no_further_than_the_window_ahead():
    read = [0]

    def lines(count):
        yield "G21 G90 G64 P0.001"
        yield "G1 X10 Y0 F1200"
        for i in range(1, count + 1):
            read[0] = i
            yield f"X{10 * math.cos(5e-4 * i):.6f} Y{10 * math.sin(5e-4 * i):.6f}"
    window = 60
    plan = stream_program(lines(5000), 2, lookahead_blocks=window, **BOUNDS)
    spans = plan.spans()
    first = next(spans)
    assert first.entry == 0.0 and first.trajectory.duration > 0.0
    assert read[0] <= window                    # two stretches a chord (a blend at each corner): W / 2 chords
    ahead = []
    for span in spans:
        ahead.append(plan.blocks_read - span.first)
    assert max(ahead) <= window + 1 and read[0] == 5000


def test_refusals_name_the_line_or_the_option():
    with pytest.raises(ProgramError, match="line 2: the program moves Z; the stream has 2 axes"):
        list(stream("G1 X1 F100\nG1 Z1\nG1 X2\n", 2, 10).spans())
    with pytest.raises(ProgramError, match="line 1: G1 before any feed rate"):
        list(stream("G1 X1\nG1 X2 F100\n", 2, 10, feedrate=0.01).spans())
    with pytest.raises(ProgramError, match=r"line 4: after the program end \(% on an earlier line\)"):
        list(stream("%\nG1 X1 F100\n%\nG1 X2\n", 2, 10).spans())
    with pytest.raises(ValueError, match="lookahead_blocks: 0"):
        stream("G1 X1 F100\n", 2, 0)
    assert [s.length for s in stream("%\nG1 X1 F100\nM30\n%\n", 2, 10).spans()] == [pytest.approx(1e-3)]


def test_memory_is_bounded_by_the_window_not_the_program():
    """The peak of the memory Python allocates while a program streams through the plan and its reference is
    sampled is the same for 500 and 5,000 chords (a whole-program plan holds about 4 kB a block)."""
    import tracemalloc

    def peak(chords):
        lines = (f"X{10 * math.cos(5e-4 * i):.6f} Y{10 * math.sin(5e-4 * i):.6f}" if i else "G64 P0.001 G1 X10 F1200"
                 for i in range(chords + 1))
        tracemalloc.start()
        for _ in stream_program(lines, 2, lookahead_blocks=200, **BOUNDS).samples(1e-3):
            pass
        _, top = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        return top
    peak(500)                                   # once before: what the first run allocates for good
    short, long = peak(500), peak(5000)
    # ten times the program, not ten times the memory (what else the process has cached moves the peak a
    # little); a window of the whole program holds about 13 MB for 5,000 chords
    assert long < 1.5 * short + 1e5 and long < 2e6
