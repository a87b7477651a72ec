"""Results per block of a part program run, and the scores of its cutting moves alone (contouring_ros/records/blocks.py)."""
import csv

import numpy as np
import pytest

from contouring_ros.records.bag_writer import write_simulation
from contouring_ros.records.blocks import block_results, cutting_scores, cutting_steps
from contouring_ros.cli import main
from contouring_ros.config import build_loop, load_experiment
from contouring_ros.core.geometry import ExactContourError
from contouring_ros.core.simulation import simulate
from contouring_ros.records.scoring import cutting_lines, score_run
from conftest import CONFIG

PROGRAM = """%
O0042
G21 G17 G40 G90 G94
G64 P0.5
N10 G0 X10 Y10
N15 X20 Y0
G61
N20 G1 X30 F1200
N30 Y10
N40 G3 X20 Y20 I-10 J0 F900
N50 G0 X0 Y0
M30
%
"""

EXPERIMENT = """/**:
  ros__parameters:
    sample_time: 0.001
    axes: ["x", "y"]
    curve: {{type: gcode, file: part.ngc}}
    schedule: {{type: feedrate, acceleration: 2.0, jerk: 40.0, rapid_feedrate: 0.1{extra}}}
/x/plant:
  ros__parameters: {{model: first_order_velocity, gain: 10.0, time_constant: 0.005}}
/y/plant:
  ros__parameters: {{model: first_order_velocity, gain: 10.0, time_constant: 0.005}}
/x/servo:
  ros__parameters: {{law: pid, kp: 20.0}}
/y/servo:
  ros__parameters: {{law: pid, kp: 20.0}}
/contour_estimator:
  ros__parameters: {{type: tangent_line}}
/ccc:
  ros__parameters: {{type: none}}
"""


@pytest.fixture(scope="module")
def part_run(tmp_path_factory):
    directory = tmp_path_factory.mktemp("blocks")
    (directory / "part.ngc").write_text(PROGRAM)
    path = directory / "part.yaml"
    path.write_text(EXPERIMENT.format(extra=", contour_tolerance: 2.0e-4, tracking_lag: [0.05]"))
    experiment = load_experiment(path)
    loop = build_loop(experiment)
    result = simulate(loop)
    return directory, experiment, loop, result


def test_every_block_is_named_with_its_feeds_time_and_errors(part_run):
    _, experiment, loop, result = part_run
    rows = block_results(loop.curve, result, loop.schedule, 2e-4)
    assert [(r.line, r.number, r.code) for r in rows] == [(5, 10, "G0"), (6, 15, "G0"), (8, 20, "G1"),
                                                          (9, 30, "G1"), (10, 40, "G3"), (11, 50, "G0")]
    assert [r.programmed_feed for r in rows[2:5]] == pytest.approx([0.02, 0.02, 0.015])
    assert rows[0].programmed_feed == pytest.approx(0.1) and rows[5].programmed_feed == pytest.approx(0.1)
    for row in rows:
        assert 0.0 < row.peak_feed <= row.programmed_feed * 1.1      # the axes, leaving the rapid at speed
        assert 0.0 < row.mean_feed < row.peak_feed
    assert sum(r.time for r in rows) == pytest.approx(result.time[-1] + 1e-3)     # every step in one block
    errors = ExactContourError(loop.curve)(result.position, near=result.theta).distance
    assert max(r.max_contour_error for r in rows) == errors.max()
    tracking = np.abs(result.reference_position - result.position).max(axis=0)
    assert np.allclose(np.max([r.max_following_error for r in rows], axis=0), tracking)
    assert {r.verdict for r in rows} <= {"held", "exceeded"}


def test_cutting_scores_leave_out_the_rapids_and_the_start_up(part_run):
    _, experiment, loop, result = part_run
    kept = cutting_steps(loop.curve, result)
    rows = block_results(loop.curve, result, loop.schedule)
    cutting = cutting_scores(loop.curve, result)
    assert cutting.steps == kept.sum() < len(result.time)
    assert cutting.mce == pytest.approx(max(r.max_contour_error for r in rows if r.code != "G0"))
    whole = score_run(loop.curve, result)
    assert whole.mce > 2 * cutting.mce          # the rapids, blended at speed, err most, and do not count
    lines = cutting_lines(loop.curve, result, experiment)
    assert lines[0].startswith("cutting moves (G1/G2/G3") and f"{cutting.mce * 1e6:.4g} um" in lines[0]
    assert f"(MCE {cutting.mce * 1e6:.4g} um)" in lines[1]       # the tolerance verdict on the cutting moves


def test_the_blocks_command_prints_the_table_and_writes_csv(part_run, capsys):
    directory, experiment, loop, result = part_run
    bag = write_simulation(directory / "part.mcap", experiment, result)
    main(["blocks", str(bag), "--csv", str(directory / "out")])
    printed = capsys.readouterr().out
    assert "cutting moves" in printed and "G3" in printed
    with open(directory / "out" / "part_blocks.csv") as stream:
        table = list(csv.DictReader(stream))
    assert [row["N"] for row in table] == ["10", "15", "20", "30", "40", "50"]
    assert set(table[0]) >= {"line", "G", "programmed_feed_mm_per_min", "mean_feed_mm_per_min",
                             "peak_feed_mm_per_min", "time_s", "max_contour_error_um", "max_following_error_x_um",
                             "tolerance"}
    assert float(table[2]["programmed_feed_mm_per_min"]) == pytest.approx(1200.0)
    assert table[2]["time_s"].count(".") == 1 and len(table[2]["time_s"].split(".")[1]) == 3     # to 1 ms
    for row in table:      # errors to 1 nm: no 2.1684e-13
        assert all(len(row[c].split(".")[1]) == 3 and "e" not in row[c] for c in row if c.endswith("_um"))
    table_lines = printed.split("feeds [mm/min]")[1].splitlines()[:8]      # the caption, headings, 6 rows
    assert table_lines[1].split()[:3] == ["line", "N", "G"] and table_lines[-1].split()[1] == "50"
    width = max(len(line) for line in table_lines) + len("feeds [mm/min]")
    assert width <= 100, f"the table is {width} columns wide"


def test_the_html_report_has_the_per_block_table(part_run):
    from contouring_ros.records.html_report import html_report
    from contouring_ros.records.scoring import read_run
    directory, experiment, loop, result = part_run
    bag = write_simulation(directory / "report.mcap", experiment, result)
    run = read_run(bag)
    page = html_report([("part", run)], [score_run(loop.curve, result)], directory / "report.html",
                       drawn={}).read_text()
    table = page.split("<h2>Per block</h2>")[1].split("</table>")[0]
    assert "Cutting moves" in table and table.count("<tr>") == 7          # the headings and six blocks
    assert "<td>G3</td>" in table and "<td>40</td>" in table


def _example(settings=None):
    from contouring_ros.api import load_experiment as load, simulate as run
    return run(load(CONFIG / "gcode_example_part.yaml"), settings)


def test_the_travel_time_ends_with_the_last_motion_not_the_reserve():
    run = _example()
    result, loop = run.result, run.loop
    moving = np.flatnonzero(result.theta != result.theta[-1])
    stopped = result.time[moving[-1] + 1]            # the reference has come to rest at the program's end
    assert result.time[-1] - stopped > 2.0           # the run keeps a reserve of in-position timeouts
    travel = run.scores().travel_time
    assert abs(travel - stopped) <= 5e-3
    waited = sum(steps - 1 for _, steps in loop.clock.waits) * 1e-3     # held steps beyond the one it passes in
    assert travel == pytest.approx(loop.schedule.duration + waited, abs=3e-3)     # the plan and its waits
    # without an in-position check the motion ends when the reference stops
    plain = _example({"in_position": [0.0]})
    assert plain.scores().travel_time == pytest.approx(plain.loop.schedule.duration, abs=1.5e-3)


def test_each_blocks_time_and_mean_feed_are_the_plans():
    run = _example({"in_position": [0.0]})          # no waits: each block takes its planned time
    plan, curve, result = run.loop.schedule, run.loop.curve, run.result
    from contouring_ros.records.scoring import motion_steps
    rows = block_results(curve, result, plan, end=motion_steps(curve, result, run.experiment))
    times = plan.block_times
    assert len(rows) == 8
    for row in rows:
        members = [i for i, b in enumerate(curve.blocks) if b.line == row.line]
        planned = times[members[-1] + 1] - times[members[0]]
        length = sum(curve.blocks[i].length for i in members)
        assert row.time == pytest.approx(planned, abs=1.5e-3), row.line
        assert row.mean_feed == pytest.approx(length / planned, rel=1.5e-3 / planned), row.line     # a step
        assert row.mean_feed < row.programmed_feed          # it starts and ends at rest
    assert rows[0].mean_feed * 60e3 == pytest.approx(10.0 / rows[0].time * 60.0, rel=1e-9)     # 10 mm side


def test_results_are_in_the_programs_units(tmp_path):
    from contouring_ros.records.blocks import block_cells, feed_unit
    from contouring_ros.core.curves import ToolPath
    from contouring_ros.core.gcode import INCH, parse_program
    program = parse_program("G20 G90\nG1 X1 F10\nG21 G1 X30\n")
    curve = ToolPath.from_program(program)
    curve.program = program
    assert program.unit == INCH and feed_unit(curve) == (INCH, "in/min")
    from contouring_ros.records.blocks import BlockResult
    row = BlockResult(2, None, "G1", 10 * INCH / 60.0, 5 * INCH / 60.0, 10.5 * INCH / 60.0, 1.0, 2.1684e-19,
                      (0.0, -1e-20), "-")
    cells = block_cells(row, curve, 1e-3)
    assert cells[3:10] == ["10.000", "5.000", "10.500", "1.000", "0.000", "0.000", "0.000"]
