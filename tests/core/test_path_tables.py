"""A tool path held as rows of arrays (core/path_tables.py) reads back the same numbers as the path streamed
block by block, which builds each stretch as an object; a program read without keeping its blocks
(gcode.read_program) gives the blocks parse_program gives."""
import numpy as np
import pytest

from contouring_ros.core import gcode
from contouring_ros.core.batch import deep_equal
from contouring_ros.core.curves import ToolPath

PROGRAM = ("G21 G90 G17 G64 P0.01\nN10 G1 X10 Y0 F1200\nN20 Y10\nG4 P0.2\nG0 X20\nG1 X25 Y12 F600\n"
           "G2 X35 Y12 I5 J0\nG3 X40 Y17 Z-1 I0 J5\nG61 G1 X45\nG64 P0.02 G1 X50 Y20\nX55 Y20.001\nM30\n")


@pytest.mark.parametrize("text", [PROGRAM, PROGRAM.replace(" Z-1", "")], ids=["helical", "planar"])
def test_the_tables_read_back_what_the_stream_builds(text):
    program = gcode.parse_program(text)
    path = ToolPath.from_program(program, blend_tolerance=0.005)
    streamed = list(ToolPath.stream(program.blocks, program.dimension, blend_tolerance=0.005))
    assert len(path.blocks) == len(path.segments) == len(streamed) > 10
    assert {b.kind for b in path.blocks} == {"line", "rapid", "arc", "blend"}
    for i, ((segment, plain), block) in enumerate(streamed):
        assert path.segments.plain(i) == (segment, plain)
        assert deep_equal(path.blocks[i], block)
    assert deep_equal(path.blocks[-1], path.blocks[len(path.blocks) - 1]) and len(path.blocks[2:5]) == 3
    assert np.array_equal(path.blocks.column("start"), [b.start for _, b in streamed])
    feeds = path.blocks.column("feed")
    assert np.isnan(feeds[[b.feed is None for _, b in streamed]]).all()
    # the scalar path and the vectorised one agree on every segment
    theta = np.linspace(0.0, path.domain[1], 997)
    columns = path.derivatives(theta, order=3)
    assert np.allclose([path.derivatives(float(t), order=3) for t in theta[::50]], columns[:, ::50].transpose(1, 0, 2),
                       rtol=0, atol=1e-12)


def test_a_program_read_without_its_blocks_gives_the_same_blocks_and_sources():
    text = PROGRAM.replace("G64 P0.02", "G64 P0.02 Q0.005")
    whole, read = gcode.parse_program(text), gcode.read_program(text.splitlines())
    assert deep_equal(list(read.blocks), whole.blocks) and deep_equal(list(read.blocks), whole.blocks)
    assert (read.dimension, read.has_feed_words, read.warnings, read.dwell, read.unit) == \
        (whole.dimension, whole.has_feed_words, whole.warnings, whole.dwell, whole.unit)
    assert read.sources.number(2) == 10 and read.sources.number(3) == 20 and read.sources.number(5) is None
    assert read.sources.codes([2, 5, 7, 8, 1]) == ["G1", "G0", "G2", "G3", None]


def test_a_feed_move_before_the_first_f_word_is_refused_the_same_way():
    text = "G21 G90\nG1 X1\nG1 X2 F100\n"
    with pytest.raises(gcode.ProgramError) as whole:
        gcode.parse_program(text)
    with pytest.raises(gcode.ProgramError) as read:
        gcode.read_program(text.splitlines())
    assert str(read.value) == str(whole.value) == "line 2: G1 before any feed rate (F)"
