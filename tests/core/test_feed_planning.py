"""Feed planning along part programs (core/feed_planning.py): analytic S-curve durations, the bounds held,
corners, blending, F as each block's bound, the contour-tolerance planner, and the experiment-file side."""
import dataclasses
import math

import numpy as np
import pytest

from contouring_ros import notices
from contouring_ros.config import build_loop, load_experiment
from contouring_ros.core.curves import ToolPath
from contouring_ros.core.feed_planning import (BlockLimit, FeedPlan, joins_span, junction_speed, reach,
                                                  scurve_distance, scurve_time, tolerance_feed)
from contouring_ros.core.gcode import parse_program
from contouring_ros.core.geometry import ExactContourError
from contouring_ros.core.simulation import simulate
from contouring_ros.errors import ConfigError
from contouring_ros.experiment.catalogue import schedules
from contouring_ros.studies.paper import CONFIG_DIR
from contouring_ros.records.scoring import score_run, tolerance_line

DT = 1e-4


def plan(text, blend=0.0, **kwargs):
    path = ToolPath.from_program(parse_program(text), blend_tolerance=blend)
    return path, FeedPlan(path, **kwargs)


def sampled(schedule):
    t = np.arange(0.0, schedule.duration + DT, DT)
    return t, *schedule(t)


def rest_to_rest_time(length, v, a, j):
    """Closed-form duration of a rest-to-rest jerk-limited move (Biagiotti and Melchiorri 2008, sec. 3.4)."""
    ramp = v / a + a / j if v * j >= a * a else 2.0 * math.sqrt(v / j)
    if length >= v * ramp:                                   # cruises at v
        return length / v + ramp
    if length >= 2.0 * a**3 / j**2:                          # reaches a, not v
        peak = a * (-a / j + math.sqrt((a / j) ** 2 + 4.0 * length / a)) / 2.0
        return 2.0 * (peak / a + a / j)
    return 4.0 * (length / (2.0 * j)) ** (1.0 / 3.0)         # reaches neither


@pytest.mark.parametrize("length_mm, feed, a, j", [
    (20.0, 0.02, 1.0, 20.0),        # cruise, acceleration limit reached
    (20.0, 0.02, 0.8, 20.0),        # cruise, the acceleration never reaches its bound (v j < a^2)
    (0.5, 0.05, 0.5, 20.0),         # no cruise, reaches a
    (0.05, 0.05, 1.0, 20.0),        # reaches neither v nor a
    (30.0, 0.04, 2.0, 5.0),         # cruise, jerk-dominated ramp
])
def test_rest_to_rest_duration_is_the_closed_form(length_mm, feed, a, j):
    _, schedule = plan(f"G1 X{length_mm} F{feed * 60000}", acceleration=a, jerk=j)
    assert schedule.duration == pytest.approx(rest_to_rest_time(length_mm * 1e-3, feed, a, j), rel=1e-9)


def test_scurve_time_both_regimes():
    assert scurve_time(0.02, 1.0, 100.0) == pytest.approx(0.02 / 1.0 + 1.0 / 100.0)     # reaches a: A^2 / J <= dv
    assert scurve_time(0.02, 1.0, 20.0) == pytest.approx(2 * math.sqrt(0.02 / 20.0))     # does not
    assert scurve_time(-0.02, 1.0, 20.0) == scurve_time(0.02, 1.0, 20.0)


PROGRAM = """G21 G17
G1 X10 F1200
G1 X20 Y5 F900
G3 X30 Y15 I0 J10
G1 Y25 F600
G2 X20 Y35 I-10 J0 Z-3
G0 X0 Y0 Z0
"""


@pytest.mark.parametrize("blend", [0.0, 5e-5])
def test_acceleration_and_jerk_bounds_hold_along_the_path(blend):
    a, j = 0.8, 15.0
    _, schedule = plan(PROGRAM, blend, acceleration=a, jerk=j, rapid_feedrate=0.05)
    t, s, v, acc = sampled(schedule)
    assert np.all(np.diff(s) >= -1e-15)                       # never backwards
    assert np.abs(acc).max() <= a * (1 + 1e-9)
    assert np.abs(acc).max() >= 0.5 * a                       # and they are used
    jerk = np.diff(acc) / DT
    assert np.abs(jerk).max() <= j * (1 + 1e-6)
    velocity = np.gradient(s, DT)
    assert np.allclose(velocity[1:-1], v[1:-1], atol=a * DT)   # theta_dot is the derivative of theta
    assert s[-1] == pytest.approx(schedule.theta_end)


def test_per_axis_bounds_on_a_diagonal_line():
    # along (3, 4)/5: x may accelerate at 0.3 -> 0.5 along the path; y at 1.0 -> 1.25; the path bound is 2
    path, schedule = plan("G1 X30 Y40 F6000", acceleration=2.0, jerk=40.0, axis_acceleration=[0.3, 1.0])
    _, _, v, acc = sampled(schedule)
    assert np.abs(acc).max() == pytest.approx(0.5, rel=1e-6)
    assert np.abs(acc * 0.6).max() <= 0.3 * (1 + 1e-9)
    _, limited = plan("G1 X30 Y40 F6000", acceleration=2.0, jerk=40.0, axis_feedrate=[0.03, 1.0])
    assert sampled(limited)[2].max() == pytest.approx(0.05, rel=1e-9)     # x at 0.03 m/s: 0.05 along the path


def test_exact_stop_at_every_corner_and_none_where_blocks_meet_tangentially():
    path, schedule = plan("G1 X10 F1200\nX20\nY10\nG3 X10 Y20 I-10 J0\nG1 X0", acceleration=1.0, jerk=20.0)
    # X10 -> X20 collinear: passes through at F; X20 -> Y10 a corner: stops; Y10 -> arc tangent; arc -> X0 tangent
    assert schedule.junctions[1] == pytest.approx(0.02)
    assert schedule.junctions[2] == 0.0
    assert schedule.junctions[3] > 0.0 and schedule.junctions[4] > 0.0
    corner = path.blocks[2].start
    _, v, _ = schedule(schedule.block_times[2])
    assert v == 0.0
    near = schedule(np.linspace(schedule.block_times[2] - 0.02, schedule.block_times[2] + 0.02, 401))
    assert near[0].min() <= corner <= near[0].max() and np.abs(near[1]).min() < 1e-9


def test_exact_stop_dwell_holds_at_the_corner():
    _, schedule = plan("G1 X10 F1200\nY10", acceleration=1.0, jerk=20.0, dwell=0.25)
    _, plain = plan("G1 X10 F1200\nY10", acceleration=1.0, jerk=20.0)
    assert schedule.duration == pytest.approx(plain.duration + 0.25)
    start = schedule.block_times[1]
    for t in (start, start + 0.1, start + 0.25):
        assert schedule(t) == (pytest.approx(0.01), 0.0, 0.0)


def test_blending_keeps_the_feed_through_corners_within_its_bounds():
    square = "G1 X10 F1200\nY10\nX0\nY0"
    path, blended = plan(square, 1e-4, acceleration=1.0, jerk=20.0)
    _, exact = plan(square, acceleration=1.0, jerk=20.0)
    assert blended.duration < exact.duration
    arcs = [i for i, b in enumerate(path.blocks) if b.kind == "blend"]
    assert len(arcs) == 3
    for i in arcs:
        kappa = path.blocks[i].curvature
        bound = min(0.02, math.sqrt(1.0 / kappa), (20.0 / kappa**2) ** (1 / 3))
        assert blended.junctions[i] == pytest.approx(bound)      # enters the blend at its limit, not 0
        t = np.linspace(blended.block_times[i], blended.block_times[i + 1], 50)
        assert blended(t)[1].max() <= bound * (1 + 1e-9)
        assert blended(t)[1].max() ** 2 * kappa <= 1.0 * (1 + 1e-9)   # centripetal acceleration bound


def test_feed_never_exceeds_each_blocks_f_and_reaches_it():
    path, schedule = plan("G1 X20 F1800\nG1 X40 F600\nG1 X60 F1200\nG0 X0 Y5", acceleration=1.0, jerk=30.0,
                          rapid_feedrate=0.08)
    t, s, v, _ = sampled(schedule)
    limits = schedule.feed_limit_at(s)
    assert np.all(v <= limits * (1 + 1e-9))
    for block, expected in zip(path.blocks, (0.03, 0.01, 0.02, 0.08)):
        inside = (s > block.start) & (s < block.start + block.length)
        assert v[inside].max() == pytest.approx(expected, rel=1e-6)
    # look-ahead: the fast block brakes before the slow one instead of entering it too fast
    assert schedule.junctions[1] == pytest.approx(0.01)


def test_feed_from_the_schedule_without_f_words_and_refusals():
    path = ToolPath.from_program(parse_program("G1 X10\nG0 X0"))
    schedule = FeedPlan(path, 1.0, 20.0, feedrate=0.015, rapid_feedrate=0.05)
    assert sampled(schedule)[2].max() == pytest.approx(0.05)
    with pytest.raises(ValueError, match="line 2: a rapid move"):
        FeedPlan(path, 1.0, 20.0, feedrate=0.015)
    with pytest.raises(ValueError, match="line 1: no feed rate"):
        FeedPlan(path, 1.0, 20.0, rapid_feedrate=0.05)


def test_tolerance_feed_is_the_first_order_lag_model():
    # a circle of radius 5 mm, lag 50 ms, tolerance 50 um: v^2 tau^2 kappa / 2 = T
    v = tolerance_feed(50e-6, [0.05, 0.05], [1.0, 0.0], 200.0)
    assert v**2 * 0.05**2 * 200.0 / 2 == pytest.approx(50e-6)
    # a line at 45 degrees with lags 40 and 50 ms: normal lag v |tau_x - tau_y| / 2 = T
    u = np.array([1.0, 1.0]) / math.sqrt(2)
    assert tolerance_feed(10e-6, [0.04, 0.05], u, 0.0) * 0.01 / 2 == pytest.approx(10e-6)
    assert tolerance_feed(10e-6, [0.05, 0.05], u, 0.0) == math.inf          # equal lags: no error on lines


# position loops of gain kp [1/s] (P) around velocity drives of gain 10: a first-order lag of 1 / (10 kp)
EXPERIMENT = """/**:
  ros__parameters:
    sample_time: 0.001
    axes: ["x", "y"]
    curve: {{type: gcode, file: {file}}}
    schedule: {schedule}
/x/plant:
  ros__parameters: {{model: first_order_velocity, gain: 10.0, time_constant: 0.005}}
/y/plant:
  ros__parameters: {{model: first_order_velocity, gain: 10.0, time_constant: 0.005}}
/x/servo:
  ros__parameters: {{law: pid, kp: {kp}}}
/y/servo:
  ros__parameters: {{law: pid, kp: {kp}}}
/contour_estimator:
  ros__parameters: {{type: tangent_line}}
/ccc:
  ros__parameters: {{type: none}}
"""


def test_contour_tolerance_held_in_simulation_where_the_unplanned_run_exceeds_it(tmp_path):
    # P position loops (kp 2) around velocity drives (gain 10): a first-order lag of 1 / (10 * 2) = 50 ms
    (tmp_path / "circle.ngc").write_text("G21 G17 (a full circle, radius 5 mm, 50 mm/s)\nG3 X0 Y0 I5 J0 F3000\nM2\n")
    tolerance = 50e-6
    runs = {}
    for name, extra in (("free", ""), ("planned", f", contour_tolerance: {tolerance}, tracking_lag: [0.05]")):
        path = tmp_path / f"{name}.yaml"
        path.write_text(EXPERIMENT.format(file="circle.ngc", kp=2.0,
                                          schedule=f"{{type: feedrate, acceleration: 2.0, jerk: 50.0{extra}}}"))
        experiment = load_experiment(path)
        loop = build_loop(experiment)
        runs[name] = (experiment, score_run(loop.curve, simulate(loop)).mce)
    free, planned = runs["free"][1], runs["planned"][1]
    assert free > 4 * tolerance                  # unplanned: the lag's radial error
    assert planned <= tolerance                  # planned: within the bound
    assert planned >= 0.5 * tolerance            # and not by crawling
    assert tolerance_line(runs["planned"][0].schedule, planned).startswith("contour tolerance 50 um: held")
    assert "exceeded by" in tolerance_line(runs["planned"][0].schedule, free)
    assert tolerance_line(runs["free"][0].schedule, free) is None


SCHEDULE = "{type: feedrate, acceleration: 1.0, jerk: 20.0}"


def write(tmp_path, program, schedule=SCHEDULE, file="part.ngc"):
    (tmp_path / "parts").mkdir(exist_ok=True)
    (tmp_path / "parts" / "part.ngc").write_text(program)
    path = tmp_path / "experiment.yaml"
    path.write_text(EXPERIMENT.format(file=f"parts/{file}", schedule=schedule, kp=20.0))
    return path


def test_experiment_reads_the_program_relative_to_its_file(tmp_path):
    experiment = load_experiment(write(tmp_path, "G1 X5 F600\nY5\n"))
    resolved = str((tmp_path / "parts" / "part.ngc").resolve())
    assert experiment.curve["file"] == resolved
    # the text bags and sweeps keep names the program by its absolute path, so it reads from anywhere
    assert f'file: "{resolved}"' in experiment.text and "file: parts/part.ngc" not in experiment.text
    from contouring_ros.config import parse_experiment
    assert parse_experiment(experiment.text, "a bag's copy").curve["file"] == resolved
    loop = build_loop(experiment)
    assert loop.curve.domain[1] == pytest.approx(0.01)
    # the in-position check (on by default) lets each exact stop wait up to in_position_timeout (0.5 s)
    assert len(loop.schedule.stops) == 1
    assert experiment.duration == pytest.approx(loop.schedule.duration + 0.5)


@pytest.mark.parametrize("program, schedule, fragment", [
    ("G1 X5 F600\nG41 X6", SCHEDULE, "part.ngc: line 2: unsupported word G41"),
    ("G1 X5 F600", "{type: feedrate, acceleration: 1.0}", "schedule.jerk: missing required key"),
    ("G1 X5 F600", "{type: feedrate, acceleration: 1.0, jerk: 20.0, feedrate: 0.01}",
     "schedule.feedrate: the part program sets its feeds with F words"),
    ("G1 X5", SCHEDULE, "line 1: no feed rate"),
    ("G1 X5 F600\nG0 X0", SCHEDULE, "line 2: a rapid move (G0) needs the schedule's rapid_feedrate"),
    ("G1 X5 F600", "{type: feedrate, acceleration: 1.0, jerk: 20.0, contour_tolerance: 1.0e-5}",
     "schedule.tracking_lag: missing required key"),
    ("G1 X5 F600", "{type: feedrate, acceleration: 1.0, jerk: 20.0, axis_jerk: [1.0, 2.0, 3.0]}",
     "schedule.axis_jerk: expected 1 value or one per axis (2)"),
    ("G20 G1 X500 F600", SCHEDULE, "check the units"),
    ("G1 X5000 Y5000 F1", SCHEDULE, "check the part program's units (G20 inch, G21 mm) and feeds"),
])
def test_experiment_refusals_are_one_line_naming_key_file_and_line(tmp_path, program, schedule, fragment):
    with pytest.raises(ConfigError) as error:
        load_experiment(write(tmp_path, program, schedule))
    assert fragment in str(error.value) and "\n" not in str(error.value)


def test_start_takes_two_or_three_coordinates(tmp_path):
    path = write(tmp_path, "G1 X5 F600")
    path.write_text(path.read_text().replace("file: parts/part.ngc", "file: parts/part.ngc, start: [0.0, 0.0, 0.0, 1.0]"))
    with pytest.raises(ConfigError, match="curve: start: expected 2 or 3 coordinates"):
        load_experiment(path)


def test_missing_program_file_is_named(tmp_path):
    with pytest.raises(ConfigError, match="cannot find the part program 'parts/other.ngc'"):
        load_experiment(write(tmp_path, "G1 X5 F600", file="other.ngc"))


def test_jerk_only_for_tool_paths_and_plan_keys_only_with_jerk(tmp_path):
    text = EXPERIMENT.replace("{{type: gcode, file: {file}}}", "{{type: circle, radius: 0.01}}")
    path = tmp_path / "circle.yaml"
    path.write_text(text.format(file="", kp=20.0, schedule="{type: feedrate, feedrate: 0.01, acceleration: 1.0, jerk: 5.0}"))
    with pytest.raises(ConfigError, match="schedule.jerk: the jerk-limited feed plan runs along a tool path"):
        load_experiment(path)
    path.write_text(text.format(file="", kp=20.0, schedule="{type: feedrate, feedrate: 0.01, acceleration: 1.0, "
                                                  "rapid_feedrate: 0.1}"))
    with pytest.raises(ConfigError, match="schedule.rapid_feedrate: applies to the jerk-limited feed plan"):
        load_experiment(path)
    for key in ("feed_override: 50", "in_position_timeout: 2.0"):
        path.write_text(text.format(file="", kp=20.0, schedule=f"{{type: feedrate, feedrate: 0.01, acceleration: "
                                                                 f"1.0, {key}}}"))
        with pytest.raises(ConfigError, match=f"schedule.{key.split(':')[0]}: applies to the jerk-limited"):
            load_experiment(path)


@pytest.mark.slow
def test_example_part_square_corners_under_20_um_and_feeds_within_f():
    experiment = load_experiment(CONFIG_DIR / "gcode_example_part.yaml")
    loop = build_loop(experiment)
    result = simulate(loop)
    error = ExactContourError(loop.curve)(result.position, near=result.theta).distance
    path, schedule = loop.curve, loop.schedule
    starts = np.array([b.start for b in path.blocks])
    block = np.clip(np.searchsorted(starts, result.theta, side="right") - 1, 0, len(starts) - 1)
    square = [i for i, b in enumerate(path.blocks) if b.kind == "line"][:4]
    assert [path.blocks[i].line for i in square] == [5, 6, 7, 8]
    assert error[np.isin(block, square)].max() < 20e-6
    feed = np.linalg.norm(result.reference_velocity, axis=1)
    limit = np.array([b.feed if b.feed is not None else schedule.limits[i].feed for i, b in enumerate(path.blocks)])
    assert np.all(feed <= limit[block] * (1 + 1e-9))
    assert feed[np.isin(block, square)].max() == pytest.approx(0.02)          # F1200: 20 mm/s, reached


def test_tool_path_runs_get_the_feed_and_per_block_figure(tmp_path):
    from contouring_ros.records.figures import figures
    from contouring_ros.records.bag_writer import write_simulation
    from contouring_ros.records.scoring import read_run
    path = write(tmp_path, "G1 X3 F600 (a corner)\nY3\nG2 X6 Y3 R1.5\n", SCHEDULE)
    experiment = load_experiment(path)
    loop = build_loop(experiment)
    bag = write_simulation(tmp_path / "run.mcap", experiment, simulate(loop))
    drawn = figures([("run", read_run(bag))])
    assert "feed" in drawn
    top, bottom = drawn["feed"].axes[:2]
    assert [tick.get_text() for tick in bottom.get_xticklabels()] == ["line 1\nG1", "line 2\nG1", "line 3\nG2"]
    heights = [patch.get_height() for patch in bottom.patches]
    assert len(heights) == 3 and all(h > 0 for h in heights)
    feed = top.lines[0].get_ydata()
    assert max(feed) == pytest.approx(600.0)                       # mm/min, the program's unit: F600
    assert bottom.get_xlabel() == "block (by its source line)" and top.get_ylabel() == "feed [mm/min]"
    circle = CONFIG_DIR / "paper003_ellipse_first_order_fn60.yaml"
    from conftest import shortened
    other = tmp_path / "ellipse.yaml"
    other.write_text(shortened(circle, 0.05))
    experiment = load_experiment(other)
    bag = write_simulation(tmp_path / "ellipse.mcap", experiment, simulate(build_loop(experiment)))
    assert "feed" not in figures([("ellipse", read_run(bag))])


def test_long_simulations_show_progress(tmp_path, capsys):
    loop = build_loop(load_experiment(write(tmp_path, "G1 X2 F600\n")))
    simulate(loop, progress=True)
    assert "step" in capsys.readouterr().err
    simulate(loop)
    assert capsys.readouterr().err == ""


def test_inline_tool_paths_take_the_jerk_limited_plan_with_the_schedule_feedrate(tmp_path):
    text = EXPERIMENT.replace("{{type: gcode, file: {file}}}",
                              '{{type: toolpath, start: [0.0, 0.0], moves: ["G1 X0.01 Y0", "G1 X0.02 Y0", '
                              '"G3 X0.03 Y0.01 I0 J0.01"]}}')
    path = tmp_path / "inline.yaml"
    path.write_text(text.format(file="", kp=20.0, schedule="{type: feedrate, feedrate: 0.02, acceleration: 1.0, jerk: 20.0}"))
    schedule = build_loop(load_experiment(path)).schedule
    assert isinstance(schedule, FeedPlan)
    assert schedule.junctions[1] == pytest.approx(0.02)           # collinear: no stop
    assert schedule.junctions[2] == pytest.approx(0.02)           # line into a tangent arc: no stop
    assert sampled(schedule)[2].max() == pytest.approx(0.02)


@pytest.mark.slow
def test_a_fifty_millimetre_square_at_fifty_mm_per_second_keeps_its_corners(tmp_path):
    # the example's axes on another program: a 50 mm square at F3000, arcs, a helix, a rapid
    program = ("(50 mm square at 50 mm/s)\nG21 G90 G17\nN1 G1 X50 F3000\nN2 Y50\nN3 X0\nN4 Y0\n"
               "N5 G3 X40 Y0 R20 F2000 ; half circle\nN6 G2 X0 Y0 I-20 J0\n"
               "N7 G91 G3 X0 Y0 Z-2 I10 J0 F1500 (helix)\nN8 G90 G0 Z5\nM30\n")
    (tmp_path / "square.ngc").write_text(program)
    text = (CONFIG_DIR / "gcode_example_part.yaml").read_text()
    (tmp_path / "square.yaml").write_text(text.replace("file: parts/example_part.ngc", "file: square.ngc"))
    experiment = load_experiment(tmp_path / "square.yaml")
    loop = build_loop(experiment)
    result = simulate(loop)
    error = ExactContourError(loop.curve)(result.position, near=result.theta).distance
    starts = np.array([b.start for b in loop.curve.blocks])
    block = np.searchsorted(starts, result.theta, side="right") - 1
    assert [b.line for b in loop.curve.blocks[:4]] == [3, 4, 5, 6]
    assert error[block <= 3].max() < 20e-6
    feed = np.linalg.norm(result.reference_velocity, axis=1)
    assert feed[block <= 3].max() == pytest.approx(0.05)
    assert np.all(feed <= np.array([limit.feed for limit in loop.schedule.limits])[np.clip(block, 0, None)] * (1 + 1e-9))


def test_the_newton_branch_check_is_dense_on_a_tool_path_and_unchanged_elsewhere():
    from contouring_ros.config import branch_check_settings, build_curve
    from contouring_ros.core.curves import Parabola
    part = build_curve(load_experiment(CONFIG_DIR / "gcode_example_part.yaml"))
    length = part.domain[1] - part.domain[0]
    samples, tolerance = branch_check_settings({"branch_check_samples": None, "branch_check_tolerance": None}, part)
    assert samples >= length / 5e-5 and tolerance == 1e-6
    assert branch_check_settings({"branch_check_samples": None, "branch_check_tolerance": None},
                                 Parabola(0.02, 50.0)) == (256, 1e-4)
    assert branch_check_settings({"branch_check_samples": 0, "branch_check_tolerance": 2e-4}, part) == (0, 2e-4)


@pytest.mark.slow
def test_the_newton_estimate_follows_the_path_round_exact_stop_corners():
    """At an exact-stop corner the distance to the path is stationary at the kink: without a dense branch
    check Newton's estimate stayed there while the axes moved on (0.2 mm off the exact error, example part).
    With the tool path's default check it stays within a few micrometres, and with the check off it does
    not (so the test can fail)."""
    experiment = load_experiment(CONFIG_DIR / "gcode_example_part.yaml")

    def deviation(experiment):
        loop = build_loop(experiment)
        result = simulate(loop)
        exact = ExactContourError(loop.curve)(result.position, near=result.theta).distance
        return np.max(np.abs(np.abs(result.estimate_signed) - exact))

    assert deviation(experiment) < 20e-6
    estimator = dict(experiment.estimator, branch_check_samples=0)
    assert deviation(dataclasses.replace(experiment, estimator=estimator)) > 100e-6


def chord_circle(chords, radius_mm=10.0, feed=1200, header=""):
    """A circle of ``chords`` G1 chords at F``feed`` (mm), as CAM systems write small arcs."""
    rows = [header, f"G1 X{radius_mm:.6f} Y0 F{feed}"] + [
        f"X{radius_mm * math.cos(a):.6f} Y{radius_mm * math.sin(a):.6f}"
        for a in 2 * math.pi * np.arange(1, chords + 1) / chords]
    return "\n".join(rows)


@pytest.mark.parametrize("chords", [360, 720])
@pytest.mark.parametrize("blend", [1e-6, 1e-5, 1e-4, 1e-3])
def test_a_chord_circle_runs_near_its_ideal_time_with_blending_and_never_reverses(chords, blend):
    # the circle of 720 chords of 0.087 mm at F1200 took 47 s under exact stop at every 0.5 degree junction
    path = ToolPath.from_program(parse_program(chord_circle(chords), start=(0.01, 0.0, 0.0)), blend)
    schedule = FeedPlan(path, 1.0, 10.0)            # config/gcode_example_part.yaml's bounds
    ideal = path.domain[1] / 0.02
    assert schedule.duration <= 1.2 * ideal
    t, s, v, acc = sampled(schedule)
    assert np.all(np.diff(s) >= 0.0) and v.min() >= 0.0
    assert v.max() <= 0.02 * (1 + 1e-9) and np.abs(acc).max() <= 1.0 * (1 + 1e-9)


def test_g64_in_the_program_blends_and_g61_stops_and_the_exact_stop_default_is_kept():
    circle = chord_circle(720)
    exact = FeedPlan(ToolPath.from_program(parse_program(circle)), 1.0, 10.0)
    blended = FeedPlan(ToolPath.from_program(parse_program("G64 P0.001\n" + circle)), 1.0, 10.0)
    assert exact.duration > 10 * blended.duration
    back = FeedPlan(ToolPath.from_program(parse_program("G64 P0.001\n" + circle + "\nG61\nX0 Y0\nY-5")), 1.0,
                    10.0)
    assert len(back.stops) == 1                                  # the corner after the G61 block (X0 Y0) stops


@pytest.mark.parametrize("angle_deg", [5.0, 30.0, 90.0, 135.0])
def test_junction_speed_is_grbls_junction_deviation_formula(angle_deg):
    phi, deviation, a, j = math.radians(angle_deg), 1e-5, 2.0, 1e6
    t0, t1 = np.array([1.0, 0.0]), np.array([math.cos(phi), math.sin(phi)])
    radius = deviation * math.cos(phi / 2) / (1 - math.cos(phi / 2))
    assert junction_speed(t0, t1, deviation, a, j) == pytest.approx(math.sqrt(a * radius), rel=1e-12)
    # the radius is that of the arc within `deviation` of the corner (LinuxCNC's blend arc for P)
    assert radius / math.cos(phi / 2) - radius == pytest.approx(deviation, rel=1e-9)
    slow_jerk = junction_speed(t0, t1, deviation, a, 1e-3)
    assert slow_jerk == pytest.approx((1e-3 * radius**2) ** (1 / 3), rel=1e-12)
    assert junction_speed(t0, t1, 0.0, a, j) == 0.0                        # exact stop
    assert junction_speed(t0, -t0, deviation, a, j) == 0.0                  # a reversal always stops
    # an axis bound along the velocity change lowers it: at 90 degrees the change is along (-1, 1)/sqrt(2)
    if angle_deg == 90.0:
        lowered = junction_speed(t0, t1, deviation, a, j, axis_acceleration=[0.5, 10.0])
        assert lowered == pytest.approx(math.sqrt(0.5 * math.sqrt(2) * radius), rel=1e-9)


def test_corners_that_may_deviate_keep_the_junction_speed_and_g9_stops_one():
    square = "G1 X10 F1200\nY10\nX0\nY0"
    for header, stops in (("G64 P0.01\n", 0), ("G61\n", 3), ("G64 P0.01\n", 1)):
        text = header + (square if header != "G64 P0.01\n" or not stops else square.replace("Y10", "Y10 G9"))
        _, schedule = plan(text, acceleration=1.0, jerk=20.0)
        assert len(schedule.stops) == stops
    # G64 P on lines rounds them; the feed at the tangent blends is their arcs' centripetal limit
    path, schedule = plan("G64 P0.01\n" + square, acceleration=1.0, jerk=20.0)
    assert [b.kind for b in path.blocks].count("blend") == 3
    # arcs meeting lines at a corner take the junction deviation, not a stop
    path, schedule = plan("G64 P0.01\nG1 X10 F1200\nG2 X20 Y0 I5 J0", acceleration=1.0, jerk=20.0)
    expected = junction_speed(path.blocks[0].tangent_out, path.blocks[1].tangent_in, 1e-5, 1.0, 20.0)
    assert 0.0 < expected < 0.02 and schedule.junctions[1] == pytest.approx(expected, rel=1e-9)


def test_reach_is_the_inverse_of_the_scurve_distance():
    for v0, length, a, j in [(0.0, 1e-5, 1.0, 10.0), (0.01, 2e-4, 1.0, 10.0), (0.0, 0.05, 0.5, 100.0),
                             (0.02, 0.01, 2.0, 50.0), (1e-6, 1e-9, 1.0, 10.0)]:
        v1 = reach(v0, length, 10.0, a, j)
        assert scurve_distance(v0, v1, a, j) == pytest.approx(length, rel=1e-9)
    assert reach(0.01, 1.0, 0.02, 1.0, 10.0) == 0.02                         # the cap


def test_g4_dwell_and_the_feed_override():
    _, dwelling = plan("G1 X10 F1200\nG4 P0.5\nX20", acceleration=1.0, jerk=20.0)
    _, plain = plan("G1 X10 F1200\nX20\nY5", acceleration=1.0, jerk=20.0)
    assert len(dwelling.stops) == 1                               # a dwell stops on a straight line too
    t0 = dwelling.stops[0, 0]
    for t in (t0, t0 + 0.25, t0 + 0.5):
        assert dwelling(t) == (pytest.approx(0.01), 0.0, 0.0)
    assert dwelling(t0 + 0.51)[1] > 0.0
    _, slow = plan("G1 X10 F1200", acceleration=1.0, jerk=20.0, feed_override=0.5)
    assert sampled(slow)[2].max() == pytest.approx(0.01, rel=1e-9)
    _, fast = plan("G1 X10 F1200\nG0 X0", acceleration=1.0, jerk=20.0, rapid_feedrate=0.05, feed_override=1.5)
    assert sampled(fast)[2].max() == pytest.approx(0.075, rel=1e-9)


HEADER_PROGRAM = "%\nO0001\nG21 G17 G40 G49 G80 G90 G94\nG54\nT1 M6\nS10000 M3\nM8\nG1 X5 F600\nY5\nM9 M5\nM30\n%\n"


def test_a_post_processors_program_runs_unedited_and_reports_its_setup_words(tmp_path):
    import contouring_ros as cr
    from contouring_ros.config import program_warnings
    path = write(tmp_path, HEADER_PROGRAM)
    run = cr.simulate(str(path))
    assert run.warnings == program_warnings(build_loop(load_experiment(path)).curve)
    assert run.warnings == ["part.ngc: lines 2-10: setup words O0001 G40 G49 G80 G94 G54 T1 M6 S10000 M3 M8 M9 M5 "
                            "read, with no effect on the path (zero work offsets; no spindle, tool or coolant is "
                            "simulated; strict: true refuses them)"]
    strict = tmp_path / "strict.yaml"
    strict.write_text(path.read_text().replace("file: parts/part.ngc}", "file: parts/part.ngc, strict: true}"))
    with pytest.raises(ConfigError) as error:
        load_experiment(strict)
    assert "part.ngc: line 2: O0001" in str(error.value) and "\n" not in str(error.value)


def test_the_feed_override_is_a_percentage_of_every_feed(tmp_path):
    plain = build_loop(load_experiment(write(tmp_path, "G1 X5 F600")))
    half = build_loop(load_experiment(write(tmp_path, "G1 X5 F600", "{type: feedrate, acceleration: 1.0, "
                                                                    "jerk: 20.0, feed_override: 50}")))
    assert sampled(half.schedule)[2].max() == pytest.approx(0.5 * sampled(plain.schedule)[2].max())
    with pytest.raises(ConfigError, match="schedule.feed_override"):
        load_experiment(write(tmp_path, "G1 X5 F600", "{type: feedrate, acceleration: 1.0, jerk: 20.0, "
                                                      "feed_override: 0}"))


def test_blending_and_junction_speeds_hold_for_turns_too_small_for_cosines():
    # a turn of 2e-9 rad: 1 / cos(phi / 2) - 1 rounds to 0 in floating point
    text = "G64 P0.001\nG1 X10 F1200\nX20 Y0.00000002\nX30 Y0.00000005"
    path, schedule = plan(text, acceleration=1.0, jerk=10.0)
    assert sampled(schedule)[2].max() == pytest.approx(0.02)
    phi = 1e-7
    t1 = np.array([math.cos(phi), math.sin(phi)])
    radius = 1e-5 * math.cos(phi / 2) / (2 * math.sin(phi / 4) ** 2)     # 1 - cos(phi / 2), without cancelling
    assert junction_speed([1.0, 0.0], t1, 1e-5, 1.0, 1e9) == pytest.approx(math.sqrt(radius), rel=1e-6)


def test_a_long_planning_says_so_on_stderr_also_off_a_terminal(tmp_path, monkeypatch, capsys):
    import time

    class SlowPlan:
        def __init__(self, *args):
            time.sleep(0.5)
            raise ValueError("stopped here")

    monkeypatch.setattr(schedules, "FeedPlan", SlowPlan)
    monkeypatch.setattr(notices, "SLOW_NOTE_AFTER", 0.1)
    monkeypatch.setattr(notices, "SLOW_NOTE_EVERY", 10.0)
    text = EXPERIMENT.replace("{{type: gcode, file: {file}}}",
                              '{{type: toolpath, start: [0.0, 0.0], moves: ["G1 X0.01 Y0", "G1 X0.02 Y0"]}}')
    path = tmp_path / "slow.yaml"
    path.write_text(text.format(file="", kp=20.0, schedule="{type: feedrate, feedrate: 0.02, acceleration: 1.0, "
                                                           "jerk: 1.0e-9}"))
    with pytest.raises(ConfigError, match="stopped here"):
        load_experiment(path)
    err = capsys.readouterr().err
    assert "note: " in err and "planning the feed along the tool path" in err and "still under way after" in err
    assert err.count("note: ") == 1


def test_a_long_simulation_off_a_terminal_says_it_is_under_way(monkeypatch, capsys):
    from contouring_ros import cli
    monkeypatch.setattr(notices, "SLOW_NOTE_AFTER", 0.0)
    monkeypatch.setattr(notices, "SLOW_NOTE_EVERY", 10.0)
    assert cli.main(["simulate", str(CONFIG_DIR / "paper000_b_ismc_h50_newton.yaml")]) == 0
    err = capsys.readouterr().err
    assert "note: simulating " in err and "steps: still under way after" in err


def _chord_circle(chords: int, radius_mm: float = 10.0) -> str:
    points = [(radius_mm * math.cos(2 * math.pi * i / chords), radius_mm * math.sin(2 * math.pi * i / chords))
              for i in range(1, chords + 1)]
    return f"G21 G90 G0 X{radius_mm} Y0\nG64 P0.001\n" + "\n".join(
        f"G1 X{x:.6f} Y{y:.6f}" + (" F1200" if i == 0 else "") for i, (x, y) in enumerate(points))


def test_a_window_that_sees_the_whole_program_plans_as_the_whole_program():
    path, whole = plan(_chord_circle(90), acceleration=1.0, jerk=10.0, rapid_feedrate=0.05)
    windowed = FeedPlan(path, 1.0, 10.0, rapid_feedrate=0.05, lookahead_blocks=len(path.blocks))
    assert windowed.duration == whole.duration
    assert np.array_equal(windowed.junctions, whole.junctions)


@pytest.mark.parametrize("window", [6, 20, 100])
def test_a_short_look_ahead_is_only_slower_and_keeps_every_bound(window):
    a, j = 1.0, 10.0
    path, whole = plan(_chord_circle(360), acceleration=a, jerk=j, rapid_feedrate=0.05)
    schedule = FeedPlan(path, a, j, rapid_feedrate=0.05, lookahead_blocks=window)
    assert schedule.duration >= whole.duration * (1 - 1e-9)
    t, s, v, acc = sampled(schedule)
    assert np.all(np.diff(s) >= -1e-15) and s[-1] == pytest.approx(schedule.theta_end)
    assert np.all(v <= schedule.feed_limit_at(s) * (1 + 1e-9))
    assert np.abs(acc).max() <= a * (1 + 1e-9)
    assert np.abs(np.diff(acc) / DT).max() <= j * (1 + 1e-6)
    # the feed at each block boundary is at most the whole program's plan there
    assert np.all(schedule.junctions <= whole.junctions * (1 + 1e-9) + 1e-12)
    if window == 6:       # 6 blocks of 0.17 mm (3 chords and their blend arcs) cannot brake from F1200: slower
        assert schedule.duration > 1.2 * whole.duration


def test_a_window_never_fixes_a_speed_the_span_before_cannot_brake_to():
    """A jerk-limited slow-down with zero acceleration at both ends needs more room from v to v / 3 than from v to
    rest, so a window that sees further may allow a speed its predecessor's span cannot brake to (the feed
    reversed on this circle of chords into a G61 line at half the feed, planned from rest at 13.2 mm, 200 %)."""
    path = ToolPath.from_program(parse_program(chord_circle(360, 5.0, header="G64 P0.001") + "\nG61 X8 Y0 F600"))
    schedule = FeedPlan(path, 1.0, 10.0, lookahead_blocks=50)
    for theta in np.linspace(0.001, 0.02, 12):
        for override in (1.0, 2.0):
            rest = schedule.rest_of_path(theta, override)
            t, s, v, acc = sampled(rest)
            assert v.min() >= -1e-12 and np.all(np.diff(s) >= -1e-15), (theta, override)
            assert np.abs(acc).max() <= 1.0 * (1 + 1e-9)


@pytest.mark.parametrize("window", [0, 50])
def test_a_plan_entered_while_moving_comes_down_to_the_new_feed_within_the_bounds(window):
    """rest_of_path from a moving state (an override to 10 % and to 50 % of F1200 on the chord circle): the feed
    runs on from the entry state, comes down to the new limit without reversing, keeps the bounds."""
    path = ToolPath.from_program(parse_program(chord_circle(360, 5.0, header="G64 P0.001")))
    schedule = FeedPlan(path, 1.0, 10.0, lookahead_blocks=window)
    theta, v0, a0 = schedule(0.05)                     # still accelerating towards F
    assert 0.0 < v0 < 0.02 and a0 > 0.0
    for override in (0.1, 0.5):
        rest = schedule.rest_of_path(float(theta), override, (float(v0), float(a0)))
        t, s, v, acc = sampled(rest)
        assert s[0] == theta and v[0] == pytest.approx(v0) and acc[0] == pytest.approx(a0)
        assert v.min() >= 0.0 and np.abs(acc).max() <= 1.0 * (1 + 1e-9)
        assert np.abs(np.diff(acc) / DT).max() <= 10.0 * (1 + 1e-6)
        down = t > 0.2                                  # 0.1 s to end the acceleration, < 0.1 s to come down
        assert v[down].max() <= 0.02 * override * (1 + 1e-9)


def test_a_block_too_short_to_use_its_higher_feed_runs_on_in_the_span_before_it():
    """joins_span: the same feed joins; a higher feed joins only where the block is too short to rise 1 %
    above the span's within its length (5 um at 7.9 mm/s: by about 1e-4), and only while the span is shorter
    than a rise by 10 % takes (147 um at 7.9 mm/s); a lower feed, a junction below the span's feed, a hold or
    other bounds start a new span."""
    head = BlockLimit(0.0079, 1.0, 10.0, "centripetal")
    line = BlockLimit(0.02, 1.0, 10.0, "F")
    assert joins_span(BlockLimit(0.0079, 1.0, 10.0, "F"), head, 0.0079, 0.0, 1e-3, 1.0)
    assert joins_span(line, head, 0.0079, 0.0, 5e-6, 0.0)
    assert reach(0.0079, 5e-6, 0.02, 1.0, 10.0) < 0.0079 * 1.001
    assert not joins_span(line, head, 0.0079, 0.0, 1e-3, 0.0)          # 1 mm: room to speed up
    assert joins_span(line, head, 0.0079, 0.0, 5e-6, 1.4e-4) and not joins_span(line, head, 0.0079, 0.0, 5e-6, 1.5e-4)
    assert scurve_distance(0.0079, 0.0079 * 1.1, 1.0, 10.0) == pytest.approx(1.47e-4, rel=0.01)
    assert not joins_span(BlockLimit(0.007, 1.0, 10.0, "F"), head, 0.007, 0.0, 5e-6, 0.0)
    assert not joins_span(line, head, 0.0078, 0.0, 5e-6, 0.0)
    assert not joins_span(line, head, 0.0079, 0.1, 5e-6, 0.0)
    assert not joins_span(BlockLimit(0.02, 2.0, 10.0, "F"), head, 0.0079, 0.0, 5e-6, 0.0)


def test_rounded_chords_are_planned_in_long_spans_near_their_blend_arcs_feed():
    """A CAM program's rounded chords, each meeting the next at a corner whose micron-long blend arc holds the
    feed to its own limit: long spans (not one per block), bounded by the lowest limit within them, so the
    mean feed is at least 60 % of the blend arcs' median limit (69 %; as one span per block, whose profiles
    start and end at zero acceleration, it was 43 %, in 635 spans), within every bound."""
    from test_feed_stream import cam_spiral
    path, whole = plan(cam_spiral(600), acceleration=1.0, jerk=10.0)
    blends = [limit.feed for block, limit in zip(path.blocks, whole.limits) if block.kind == "blend"]
    first = whole._span[0]
    assert len(blends) > 300 and len(first) < len(path.blocks) / 10
    cutting = whole.duration - whole.block_times[1]
    assert (path.domain[1] - path.blocks[1].start) / cutting >= 0.6 * float(np.median(blends))
    theta, feed, rate = whole(np.arange(0.0, whole.duration, DT))
    block = np.clip(np.searchsorted([b.start for b in path.blocks], theta, side="right") - 1, 0, None)
    assert (feed <= np.array([limit.feed for limit in whole.limits])[block] * (1 + 1e-9) + 1e-12).all()
    assert np.abs(rate).max() <= 1.0 * (1 + 1e-9) and np.all(np.diff(theta) >= 0.0)


def test_a_plan_entered_above_its_feed_plans_with_a_look_ahead_shorter_than_its_first_span():
    """An override's re-plan entered above the first block's feed keeps the window's splits off the way down,
    so its first span can be longer than the look-ahead: the span is still judged over its whole length (it
    brakes from 5.5 to 5 mm/s within it), never slower to plan than to refuse, and never faster than the
    whole plan entered alike."""
    text = "G21 G90 G64 P0.01\nG1 X0.05 Y0 F300\nG1 X2.916 Y0.887\n"
    path = ToolPath.from_program(parse_program(text))
    whole = FeedPlan(path, 1.0, 10.0, entry=(0.0055, -0.1))
    windowed = FeedPlan(path, 1.0, 10.0, lookahead_blocks=2, entry=(0.0055, -0.1))
    assert windowed.duration >= whole.duration * (1 - 1e-12)
    theta, feed, _ = windowed(np.arange(0.0, windowed.duration, DT))
    assert np.all(np.diff(theta) >= 0.0) and feed[-1] <= 1e-6
    assert feed[int(0.5 / DT)] <= 0.005 * (1 + 1e-9)
