"""Results per block of a part program run, and the scores of its cutting moves alone (contouring_ros/blocks.py)."""
import csv

import numpy as np
import pytest

from contouring_ros.bag import write_simulation
from contouring_ros.blocks import block_results, cutting_scores, cutting_steps
from contouring_ros.cli import main
from contouring_ros.config import build_loop, load_experiment
from contouring_ros.core.geometry import ExactContourError
from contouring_ros.core.simulation import simulate
from contouring_ros.scoring import cutting_lines, score_run

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
        assert 0.0 < row.achieved_feed <= row.programmed_feed * 1.1      # the axes, leaving the rapid at speed
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
    lines = cutting_lines(loop.curve, result, experiment.schedule)
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
    assert set(table[0]) >= {"line", "G", "programmed_feed_mm_per_min", "achieved_feed_mm_per_min", "time_s",
                             "max_contour_error_um", "max_following_error_x_um", "tolerance"}
    assert float(table[2]["programmed_feed_mm_per_min"]) == pytest.approx(1200.0)


def test_the_html_report_has_the_per_block_table(part_run):
    from contouring_ros.analysis import html_report
    from contouring_ros.scoring import read_run
    directory, experiment, loop, result = part_run
    bag = write_simulation(directory / "report.mcap", experiment, result)
    run = read_run(bag)
    page = html_report([("part", run)], [score_run(loop.curve, result)], directory / "report.html",
                       drawn={}).read_text()
    table = page.split("<h2>Per block</h2>")[1].split("</table>")[0]
    assert "Cutting moves" in table and table.count("<tr>") == 7          # the headings and six blocks
    assert "<td>G3</td>" in table and "<td>40</td>" in table
