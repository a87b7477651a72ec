"""Runs of plain G1 lines read, blended and made stretches as arrays (core/line_runs.py): the fast reader gives
the general reader's blocks, the chunked tool path the scalar path's stretches, and the streaming plan made
from them the windowed whole-program plan, bit for bit."""
import math
import random

import numpy as np
import pytest

from contouring_ros.core.curves import ToolPath
from contouring_ros.core.feed_planning import FeedPlan
from contouring_ros.core.feed_stream import stream_program
from contouring_ros.core.gcode import ProgramError, ProgramReader, parse_program
from contouring_ros.core.gcode import LineRun
from contouring_ros.core.line_runs import StretchChunk

#: plain G1 lines of every spelling the fast reader takes, and lines it leaves to the general reader
#: (comments, words out of order, G91, F, G64 Q, dwells, arcs, a zero-length move), between them
VARIED = """%
G21 G90 G17 G64 P0.002
G1 X0 Y0 F600
X1 Y0.5
n10 g1 x2 y1
N11 G01 X3.5Y1.25
   x4    y  -1.5
X5 (a comment) Y0
X6 Y0 ; a comment
Y0
X6 Y0
Y2
G1 X7 Y2.5 Z0.25
X8 Y3 Z-.5
Z0
G4 P0.1
X9.000 Y+3
X10. Y4
G91 X1 Y1
X1 Y-1
G90 X13 Y4 F900
X14 Y4.5
G2 X15 Y3.5 R1
G1 X16 Y3
G64 P0.001 Q0.01
X17 Y3.001
X18 Y3
X19 Y3.002
G64 P0.001
X20 Y3
G61
X21 Y4
X22 Y3
G9 X23 Y4
X24 Y3
G64
X25 Y4
X26 Y3
N12 X27 Y4
M30
%
"""


def expanded(blocks):
    for block in blocks:
        if isinstance(block, LineRun):
            yield from block.blocks()
        else:
            yield block


def fields(block):
    return (block.kind, block.start.tolist(), block.end.tolist(), block.feed, block.line,
            None if block.centre is None else block.centre.tolist(), block.plane, block.clockwise, block.tolerance,
            block.dwell, block.number, block.merge_tolerance, block.merged)


@pytest.mark.parametrize("runs", [1, 2, 3, 256])
def test_the_fast_reader_gives_the_general_readers_blocks(runs):
    lines = VARIED.splitlines()
    general, fast = ProgramReader(), ProgramReader()
    expected = [fields(b) for b in general.blocks(iter(lines))]
    read = list(fast.blocks(iter(lines), runs=runs))
    assert any(isinstance(b, LineRun) for b in read)
    assert [fields(b) for b in expanded(read)] == expected
    assert all(len(b) <= runs for b in read if isinstance(b, LineRun))
    for name in ("dimension", "has_feed", "warnings", "first_dwell", "unit"):
        assert getattr(fast, name) == getattr(general, name)


@pytest.mark.parametrize("text", ["G1 X1 F100\nX1e-3 Y2\n", "G1 X1 F100\nX2 X3\n", "G1 X1 F100\nX1e10 Y0\n",
                                  "G1 X1 F100\nX2 Y2\nX3 Y3 G2\n"])
def test_the_fast_reader_leaves_what_it_cannot_read_to_the_general_readers_message(text):
    with pytest.raises(ProgramError) as general:
        list(ProgramReader().blocks(iter(text.splitlines())))
    with pytest.raises(ProgramError) as fast:
        list(ProgramReader().blocks(iter(text.splitlines()), runs=8))
    assert str(fast.value) == str(general.value)


def zigzag(chords: int, dimension: int = 2, seed: int = 0) -> str:
    """Chords of random lengths and turns: gentle ones (blended), none (collinear), sharp ones and reversals,
    and chords so short the blend is cut back to 0.45 of them."""
    rng = random.Random(seed)
    rows, x, y, z, heading = ["G21 G90 G64 P0.005", "G1 X0 Y0 F1200"], 0.0, 0.0, 0.0, 0.0
    for _ in range(chords):
        heading += rng.choice([0.0, 1e-4, 0.01, 0.3, -1.0, 2.5, math.pi, 1e-10])
        step = rng.choice([0.001, 0.005, 0.2, 1.0])
        x, y = x + step * math.cos(heading), y + step * math.sin(heading)
        z = z + (rng.choice([0.0, 0.001]) if dimension == 3 else 0.0)
        rows.append(f"X{x:.6f} Y{y:.6f}" + (f" Z{z:.6f}" if dimension == 3 else ""))
    return "\n".join(rows) + "\n"


def stretches(blocks, dimension):
    for item in ToolPath.stream(blocks, dimension):
        if isinstance(item, StretchChunk):
            yield from (item.pair(k) for k in range(len(item)))
        else:
            yield item


def row(pair):
    (segment, plain), block = pair
    return (segment, plain, block.kind, block.start, block.length, block.feed, block.line,
            block.tangent_in.tolist(), block.tangent_out.tolist(), block.curvature, block.deviation, block.dwell)


@pytest.mark.parametrize("dimension, seed", [(2, 0), (2, 1), (3, 2)])
def test_a_runs_chunked_stretches_are_the_scalar_paths_bit_for_bit(dimension, seed):
    lines = zigzag(400, dimension, seed).splitlines()
    scalar = [row(p) for p in stretches(ProgramReader().blocks(iter(lines)), dimension)]
    chunked = list(ToolPath.stream(ProgramReader().blocks(iter(lines), runs=50), dimension))
    assert sum(isinstance(item, StretchChunk) for item in chunked) >= 8
    assert [row(p) for p in stretches(ProgramReader().blocks(iter(lines), runs=50), dimension)] == scalar


@pytest.mark.parametrize("bounds", [dict(), dict(dwell=0.05), dict(axis_acceleration=[0.5, 2.0]),
                                    dict(feed_override=0.7, normal_acceleration=0.3)])
@pytest.mark.parametrize("window", [9, 60])
def test_the_stream_of_runs_is_the_windowed_plan(bounds, window):
    text = zigzag(300, 2, 3)
    common = dict(acceleration=1.0, jerk=10.0, **bounds)
    path = ToolPath.from_program(parse_program(text))
    windowed = FeedPlan(path, lookahead_blocks=window, **common)
    spans = list(stream_program(iter(text.splitlines()), 2, lookahead_blocks=window, **common).spans())
    first, start, length, cap, acc, jerk, v, hold = windowed._span
    assert [s.first for s in spans] == list(first)
    assert [s.start for s in spans] == list(start) and [s.length for s in spans] == list(length)
    assert [s.entry for s in spans] + [spans[-1].exit] == list(v)
    assert [s.hold for s in spans] == list(hold[:-1]) and [s.cap for s in spans] == list(cap)
    if "dwell" in bounds:
        return        # the samples after a dwell's hold part from FeedPlan's in the last bit, as they did before runs
    rows = list(stream_program(iter(text.splitlines()), 2, lookahead_blocks=window, **common).samples(2e-3))
    theta, feed, rate = windowed(np.array([r[0] for r in rows]))
    assert np.array_equal(theta, [r[1] for r in rows]) and np.array_equal(feed, [r[2] for r in rows])
    assert np.array_equal(np.array([path.point(x) for x in theta]), np.array([r[4] for r in rows]))
