"""The part program reader (core/gcode.py) and the tool path it builds (ToolPath.from_program)."""
import math
import re

import numpy as np
import pytest

from contouring_ros.core.curves import ToolPath
from contouring_ros.core.gcode import ProgramError, parse_program


def blocks(text, start=(0.0, 0.0, 0.0)):
    return parse_program(text, start).blocks


def test_units_millimetres_by_default_inches_with_g20():
    (mm,) = blocks("G1 X50 F600")
    assert mm.end == pytest.approx([0.05, 0.0, 0.0])
    assert mm.feed == pytest.approx(0.01)                      # 600 mm/min = 10 mm/s
    (inch,) = blocks("G20 G1 X2 F60")
    assert inch.end == pytest.approx([0.0508, 0.0, 0.0])
    assert inch.feed == pytest.approx(60 * 0.0254 / 60)
    (metric,) = blocks("G20\nG21 G1 Y3 F60")
    assert metric.end == pytest.approx([0.0, 0.003, 0.0])


def test_incremental_and_absolute_and_modal_motion_and_feed():
    program = blocks("G91 G1 X10 F600\nX10\nY5\nG90 X0\nG0 Y0")
    ends = [b.end * 1e3 for b in program]
    assert np.allclose(ends, [[10, 0, 0], [20, 0, 0], [20, 5, 0], [0, 5, 0], [0, 0, 0]])
    assert [b.kind for b in program] == ["line", "line", "line", "line", "rapid"]
    assert [b.feed for b in program[:4]] == [pytest.approx(0.01)] * 4
    assert program[4].feed is None                                  # rapids take the schedule's rapid rate


def test_comments_line_numbers_percent_and_program_end():
    program = parse_program("%\n(a comment G2 X99)\nN10 G1 X1 F60 (inline) ; rest X99\n; a line comment\n"
                            "N20 M30\n%\n")
    assert len(program.blocks) == 1 and program.blocks[0].end[0] == pytest.approx(0.001)
    assert program.blocks[0].line == 3


def test_arc_centre_form_and_direction():
    (ccw,) = blocks("G17 G3 X10 Y10 I0 J10 F600")
    assert ccw.centre * 1e3 == pytest.approx([0, 10, 0]) and not ccw.clockwise
    (cw,) = blocks("G2 X10 Y10 I10 J0 F600")
    assert cw.centre * 1e3 == pytest.approx([10, 0, 0]) and cw.clockwise


def test_arc_radius_form_negative_r_takes_the_long_way():
    # chord (0,0)->(10,10) of a radius-10 circle: centre (0,10) (a quarter turn counter-clockwise) or (10,0)
    (short,) = blocks("G3 X10 Y10 R10 F600")
    (long,) = blocks("G3 X10 Y10 R-10 F600")
    (clockwise,) = blocks("G2 X10 Y10 R10 F600")
    assert short.centre[:2] * 1e3 == pytest.approx([0, 10], abs=1e-9)
    assert long.centre[:2] * 1e3 == pytest.approx([10, 0], abs=1e-9)
    assert clockwise.centre[:2] * 1e3 == pytest.approx([10, 0], abs=1e-9)
    lengths = [ToolPath.from_program(parse_program(f"G3 X10 Y10 R{r} F600")).domain[1] for r in (10, -10)]
    assert lengths[0] == pytest.approx(0.01 * math.pi / 2)
    assert lengths[1] == pytest.approx(0.01 * 3 * math.pi / 2)


def test_helical_arc_and_full_circle():
    program = parse_program("G3 X0 Y0 Z-2 I5 J0 F600")
    assert program.dimension == 3
    path = ToolPath.from_program(program)
    assert path.domain[1] == pytest.approx(math.hypot(2 * math.pi * 0.005, 0.002))
    assert path.point(path.domain[1]) == pytest.approx([0.0, 0.0, -0.002], abs=1e-12)
    mid = path.point(path.domain[1] / 2)
    assert mid == pytest.approx([0.010, 0.0, -0.001], abs=1e-12)          # half a turn: opposite the start
    speed = np.linalg.norm(path.derivatives(np.linspace(0, path.domain[1], 50), 1)[1], axis=-1)
    assert speed == pytest.approx(1.0)                                      # parametrised by arc length
    assert path.blocks[0].curvature == pytest.approx(0.005 / (0.005**2 + (0.002 / (2 * math.pi))**2))


@pytest.mark.parametrize("words, tangent", [
    ("G17 G2 X10 Y0 I5 J0", [0, 1, 0]),       # about +Z from (-5, 0) off the centre: clockwise goes +Y
    ("G17 G3 X10 Y0 I5 J0", [0, -1, 0]),
    ("G18 G2 X10 Z0 I5 K0", [0, 0, -1]),      # ZX plane, seen from +Y: clockwise goes -Z
    ("G18 G3 X10 Z0 I5 K0", [0, 0, 1]),
    ("G19 G2 Y10 Z0 J5 K0", [0, 0, 1]),       # YZ plane, seen from +X: clockwise goes +Z
    ("G19 G3 Y10 Z0 J5 K0", [0, 0, -1]),
])
def test_planes_clockwise_as_seen_from_the_positive_normal_axis(words, tangent):
    path = ToolPath.from_program(parse_program(f"{words} F600"))
    assert path.blocks[0].tangent_in[:path.dimension] == pytest.approx(tangent[:path.dimension], abs=1e-12)
    assert path.domain[1] == pytest.approx(math.pi * 0.005)
    end = path.point(path.domain[1])
    assert np.linalg.norm(end - np.array(parse_program(words + " F600").blocks[0].end[:path.dimension])) < 1e-15


def test_derivatives_are_those_of_the_points():
    path = ToolPath.from_program(parse_program("G1 X5 F600\nG3 X10 Y5 Z1 I0 J5\nG18 G2 X15 Z1 I2.5 K0"))
    s = np.linspace(0.0005, path.domain[1] - 0.0005, 400)
    inside = np.all(np.abs(s[:, None] - np.array([b.start for b in path.blocks])[None, :]) > 2e-6, axis=1)
    s, h = s[inside], 1e-7
    d = path.derivatives(s, 3)
    for order in (1, 2, 3):
        numeric = (path.derivatives(s + h, order - 1)[order - 1] - path.derivatives(s - h, order - 1)[order - 1]) / (2 * h)
        assert np.allclose(numeric, d[order], rtol=1e-4, atol=1e-3 * np.abs(d[order]).max())


@pytest.mark.parametrize("text, line, word", [
    ("G1 X1 F60\nG41 X2", 2, "G41"),
    ("G1 X1 F60\nG42.1 D1 X2", 2, "G42.1"),
    ("G1 X1 F60\nG43 H1", 2, "G43"),
    ("G93\nG1 X1 F60", 1, "G93"),
    ("G1 X1 F60\nG81 X2 R1 Z-1", 2, "G81"),
    ("G1 X1 F60\nG1 A10", 2, "A10"),
    ("G1 X1 F60\nM0", 2, "M0"),
])
@pytest.mark.parametrize("strict", [False, True])
def test_unsupported_motion_is_refused_in_either_mode_naming_line_and_word(text, line, word, strict):
    with pytest.raises(ProgramError) as error:
        parse_program(text, strict=strict)
    message = str(error.value)
    assert f"line {line}:" in message and word in message and "\n" not in message


POST_PROCESSOR_HEADER = """%
O1000 (a CAM post-processor's preamble)
G21 G17 G40 G49 G80 G90 G94
G54
T1 M6
S12000 M3
M8
G0 X0 Y0
G1 X10 F600
G1 Y10
M9
M5
M30
%
"""


def test_setup_words_are_read_and_reported_in_one_line():
    program = parse_program(POST_PROCESSOR_HEADER)
    assert [b.kind for b in program.blocks] == ["line", "line"]          # G0 X0 Y0 is where the tool is
    assert len(program.warnings) == 1
    line = program.warnings[0]
    assert line.startswith("lines 2-12: setup words O1000 G40 G49 G80 G94 G54 T1 M6 S12000 M3 M8 M9 M5 read,")
    assert "no effect on the path" in line and "strict: true" in line and "\n" not in line
    assert parse_program("G54\nG1 X1 F60").warnings[0].startswith("line 1: setup words G54 read")
    assert parse_program("G1 X1 F60").warnings == ()


@pytest.mark.parametrize("word, line", [("O1000", 2), ("G40", 3), ("G54", 4), ("T1", 5), ("S12000", 6),
                                        ("M8", 7)])
def test_strict_mode_refuses_each_setup_word_naming_its_line(word, line):
    text = "\n".join(row for row in POST_PROCESSOR_HEADER.splitlines()
                     if row in ("%", "M30") or word in row or row.startswith("G1"))
    with pytest.raises(ProgramError) as error:
        parse_program(text, strict=True)
    message = str(error.value)
    assert word in message and "strict" in message and "\n" not in message


def test_path_control_words_set_each_blocks_tolerance_and_dwell():
    program = parse_program("G1 X1 F60\nG64 P0.01\nX2\nX3 G9\nG4 P0.5\nX4\nG61\nX5\nG64\nX6\nG61.1 X7")
    tolerances = [b.tolerance for b in program.blocks]
    assert tolerances == [None, pytest.approx(1e-5), 0.0, pytest.approx(1e-5), 0.0, pytest.approx(1e-5), 0.0]
    assert [b.dwell for b in program.blocks] == [0, 0, 0.5, 0, 0, 0, 0]
    assert parse_program("G20 G64 P0.001\nG1 X1 F60").blocks[0].tolerance == pytest.approx(25.4e-6)
    assert parse_program("G4 P1.5\nG1 X1 F60").dwell == 1.5


@pytest.mark.parametrize("text, fragment", [
    ("G1 X1 F60\nG4", "line 2: G4 needs its dwell P"),
    ("G1 X1 F60\nG4 P1 X2", "line 2: G4 with a motion"),
    ("G1 X1 F60 P2", "line 1: P2 without G4 or G64"),
    ("G1 X1 F60 Q2", "line 1: Q2 without G64"),
    ("G64 P-1\nG1 X1 F60", "line 1: P-1: the blending tolerance"),
])
def test_path_control_mistakes_are_one_line(text, fragment):
    with pytest.raises(ProgramError, match=fragment):
        parse_program(text)


@pytest.mark.parametrize("text, fragment", [
    ("G1 X1 F60\nG1 X2 X3", "line 2: X given twice"),
    ("G1 X1\nG1 X2 F60", None),                        # no F yet on line 1 but F later: refused on line 1
    ("G2 X10 Y0 I3 J0 F60", "line 1: G2: the end point is"),
    ("G2 X10 Y0 R2 F60", "line 1: G2: R2 is shorter than half the chord"),
    ("G1 X1 F60 (open", "line 1: comment not closed"),
    ("G1 X1 F60\nM2\nG1 X2", "line 3: after the program end"),
    ("X1", "line 1: coordinates without a motion mode"),
    ("G1 X1 F-5", "line 1: F-5: the feed rate must be positive"),
    ("G1 X1 F60 R2", "line 1: R on a G1 line"),
    ("G17 G2 X1 Y1 K1 F60", "line 1: K is not a centre offset in the XY plane"),
    ("G1 X1 F60 $", "line 1: cannot read '$'"),
    ("G1 X1 F60\n/G1 X2", "line 2: block delete"),
])
def test_malformed_programs_are_refused_in_one_line(text, fragment):
    with pytest.raises(ProgramError) as error:
        parse_program(text)
    message = str(error.value)
    assert "\n" not in message
    assert (fragment or "line 1: G1 before any feed rate (F)") in message


def test_a_program_without_f_words_leaves_the_feed_to_the_schedule():
    program = parse_program("G1 X1\nG2 X3 Y0 I1 J0")
    assert not program.has_feed_words and [b.feed for b in program.blocks] == [None, None]


def test_blend_stays_within_the_tolerance_and_is_tangent():
    square = "G1 X10 F600\nY10\nX0\nY0"
    tolerance = 1e-4
    path = ToolPath.from_program(parse_program(square), blend_tolerance=tolerance)
    assert [b.kind for b in path.blocks] == ["line", "blend", "line", "blend", "line", "blend", "line"]
    corners = np.array([[0.01, 0.0], [0.01, 0.01], [0.0, 0.01]])
    s = np.linspace(0.0, path.domain[1], 20001)
    points = path.point(s)
    for corner in corners:
        nearest = np.min(np.linalg.norm(points - corner, axis=1))
        assert nearest == pytest.approx(tolerance, rel=1e-3)       # the deviation is the tolerance itself
    for before, after in zip(path.blocks[:-1], path.blocks[1:]):
        assert np.dot(before.tangent_out, after.tangent_in) == pytest.approx(1.0)
    exact = ToolPath.from_program(parse_program(square))
    assert [b.kind for b in exact.blocks] == ["line"] * 4


def test_guard_refuses_a_path_longer_than_ten_metres_with_a_units_hint():
    with pytest.raises(ValueError, match=r"m long .*units.*G21"):
        ToolPath.from_program(parse_program("G20 G1 X500 F60"))
    with pytest.raises(ValueError, match=r"G1 X50 is 50 m"):
        ToolPath([0.0, 0.0], ["G1 X50 Y0"])


def test_dimension_two_for_planar_programs_three_where_z_is_used():
    assert parse_program("G1 X1 Y1 F60").dimension == 2
    assert parse_program("G1 X1 Z0 F60").dimension == 2                   # Z named but not moved
    assert parse_program("G1 X1 Z1 F60").dimension == 3
    assert parse_program("G18 G2 X2 Z0 I1 K0 F60").dimension == 3        # an arc in ZX moves Z
    assert parse_program("G1 X1 F60", start=(0.0, 0.0, 0.01)).dimension == 3
    path = ToolPath.from_program(parse_program("G1 X1 F60", start=(0.0, 0.0, 0.01)))
    assert path.point(0.0) == pytest.approx([0.0, 0.0, 0.01])


@pytest.mark.parametrize("move, word", [("G1 X0.05 F100", "F100"), ("G1 X0.05 Z0.01", "Z0.01"),
                                        ("G2 X0.06 Y0 I0.03 J0 K0", "K0"), ("G3 X0.06 Y0 R0.03", "R0.03")])
def test_inline_moves_refuse_words_they_do_not_read(move, word):
    with pytest.raises(ValueError, match=f"move 1 .*: {word} is not read in inline moves"):
        ToolPath([0.0, 0.0], [move])


@pytest.mark.parametrize("text, line", [
    ("G1 X1 F60\nG1 X" + "9" * 400 + " F60", 2),                     # reads as infinity
    ("G1 X1 F60\nG2 X0 Y0 I" + "9" * 400 + " J0", 2),                 # an arc of infinite radius
    ("G1 X1 F60\n\nG2 X1 Y2 R" + "9" * 309 + ".5", 3),
    ("N" + "9" * 400 + " G1 X1 F60", 1),
    ("G1 X1 F" + "9" * 400, 1),
    ("G1 X1e5 F60", 1),                                               # not a number word at all
])
def test_numbers_out_of_range_are_refused_naming_the_line(text, line):
    with pytest.raises(ProgramError) as error:
        ToolPath.from_program(parse_program(text))
    message = str(error.value)
    assert message.startswith(f"line {line}: ") and "\n" not in message and len(message) < 200


def test_a_move_whose_length_or_radius_is_not_finite_is_refused_naming_its_line():
    from contouring_ros.core.gcode import Block, Program
    big = np.array([1e200, 1e200, 0.0])
    arc = Block("arc", big, big.copy(), 0.01, 7, np.array([-1e200, -1e200, 0.0]), (0, 1, 2), False)
    with pytest.raises(ValueError, match=r"^line 7: .*not a finite number"):
        ToolPath.from_program(Program([arc], 2, True))
    line = Block("line", np.zeros(3), np.array([1e308, 1e308, 0.0]), 0.01, 4)
    with pytest.raises(ValueError, match=r"^line 4: .*not a finite number"):
        ToolPath.from_program(Program([line], 2, True))


@pytest.mark.parametrize("move", ["G1 Xnan Y0", "G1 Xinf Y0", "G2 X0 Y0 I1e400 J0", "G1 X1e300 Y0", "G1 X1e7 Y0"])
def test_inline_moves_take_only_finite_numbers(move):
    with pytest.raises(ValueError, match=r"^move 1 .*finite"):
        ToolPath([0.0, 0.0], [move])


def _chords(points, header="G21 G90 G64 P0.01 Q0.001", feed=" F600"):
    lines = [header] + [f"G1 X{x:.6f} Y{y:.6f}" + (feed if i == 0 else "") for i, (x, y) in enumerate(points)]
    return "\n".join(lines)


def test_g64_q_merges_g1_blocks_within_q_of_a_line_as_linuxcnc_does():
    from contouring_ros.core.gcode import MAX_MERGED
    # ten steps along X, each end point 0.4 um off the line alternately: within Q = 1 um, one block
    wiggle = [(i, 0.0004 * (-1) ** i if i < 10 else 0.0) for i in range(1, 11)]
    program = parse_program(_chords(wiggle))
    assert len(program.blocks) == 1
    merged = program.blocks[0]
    assert merged.merged == 10 and merged.line == 2 and np.allclose(merged.end, [0.010, 0.0, 0.0])
    assert np.allclose(merged.start, 0.0) and merged.feed == pytest.approx(0.01)
    # 2 um off: beyond Q, nothing merges
    assert len(parse_program(_chords([(i, 0.002 * (-1) ** i) for i in range(1, 11)])).blocks) == 10
    # without Q (or under G61) every block stays
    assert len(parse_program(_chords(wiggle, "G21 G90 G64 P0.01")).blocks) == 10
    assert len(parse_program(_chords(wiggle, "G21 G90 G64 P0.01 Q0.001\nG61")).blocks) == 10
    # a turn of 90 degrees ends the run: two lines
    corner = [(i, 0.0) for i in range(1, 6)] + [(5, i) for i in range(1, 6)]
    assert [b.merged for b in parse_program(_chords(corner)).blocks] == [5, 5]
    # at most MAX_MERGED blocks each
    long = parse_program(_chords([(0.01 * i, 0.0) for i in range(1, 2 * MAX_MERGED + 2)]))
    assert [b.merged for b in long.blocks] == [MAX_MERGED, MAX_MERGED, 1]


def test_g64_q_does_not_merge_across_a_feed_change_a_dwell_or_a_rapid():
    text = "G21 G90 G64 P0.01 Q0.001\nG1 X1 F600\nX2\nX3 F900\nX4\nG4 P0.1\nX5\nG0 X6\nG1 X7\nX8"
    program = parse_program(text)
    assert [(b.kind, b.merged, b.line) for b in program.blocks] == [
        ("line", 2, 2), ("line", 2, 4), ("line", 1, 7), ("rapid", 1, 8), ("line", 2, 9)]
    assert program.blocks[1].dwell == pytest.approx(0.1)          # the dwell after the merged run's last block
    with pytest.raises(ProgramError, match="Q-1"):
        parse_program("G64 P0.01 Q-1\nG1 X1 F60")


def test_a_chord_circle_merges_only_where_its_chords_stay_within_q():
    import math
    circle = [(5 * math.cos(2 * math.pi * i / 720), 5 * math.sin(2 * math.pi * i / 720)) for i in range(1, 721)]
    header = "G21 G90 G0 X5 Y0\nG64 P0.01 Q{q}"
    blocks = {q: parse_program(_chords(circle, header.format(q=q))).blocks[1:] for q in (0.0001, 0.01)}
    # a run of n chords of 0.5 degree on R5 has its middle end point R (1 - cos(n / 4 degree)) off its chord:
    # 2 chords 0.19 um (over Q0.0001), 14 chords 9.3 um and 15 chords 10.7 um (Q0.01: runs of 14)
    assert len(blocks[0.0001]) == 720
    assert [b.merged for b in blocks[0.01]] == [14] * 51 + [720 - 14 * 51]
    path = ToolPath.from_program(parse_program(_chords(circle, header.format(q=0.01))))
    radius = np.linalg.norm(path.point(np.linspace(path.blocks[1].start, path.domain[1], 5000))[:, :2], axis=1)
    assert radius.min() > 5e-3 - 1e-5 - 1e-9            # within Q (10 um) of the circle


@pytest.mark.parametrize("line, message", [
    ("X1 " * 5000 + "!", "line 1: cannot read '!'"),                         # many words, then one that is not
    ("X1 Y" + "9" * 400 + " $", "line 1: Y" + "9" * 19 + "... (400 characters): the number is out of range"),
    ("G1 X1.5Y2 Z.5 # F60", "line 1: cannot read '#'"),
])
def test_a_line_is_refused_at_its_first_problem_in_the_order_it_is_written(line, message):
    """A line that is words alone is read at once; any other is read word by word up to its first problem, so
    the message names what comes first on the line, however long the line."""
    with pytest.raises(ProgramError, match="^" + re.escape(message)):
        parse_program(line + "\n")
