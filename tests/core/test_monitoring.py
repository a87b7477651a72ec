"""Monitoring during a run (contouring_ros/core/monitoring.py): a contour-error or following-error limit in the
experiment file; a breach stops the reference on the path within the plan's bounds, ends the run with one
line naming the block, and the graph does what the simulation does."""
import subprocess
import sys

import numpy as np
import pytest

from contouring_ros.config import build_loop, load_experiment
from contouring_ros.core.simulation import simulate
from contouring_ros.errors import ConfigError
from contouring_ros.records.scoring import breach_message, motion_steps, read_run
from conftest import CONFIG, ROOT

#: a fast arc (N30, F3000) between slow lines: on these axes its contour error (3.6 um) is the program's largest
PROGRAM = """%
G21 G90 G17 G61
N10 G1 X10 F600
N20 Y10
N30 G3 X0 Y10 R5 F3000
N40 G1 Y0 F600
M30
%
"""

EXPERIMENT = """/**:
  ros__parameters:
    experiment: {{name: monitored_part}}
    sample_time: 0.001
    axes: ["x", "y"]
    curve: {{type: gcode, file: part.ngc}}
    schedule: {{type: feedrate, acceleration: 1.0, jerk: 10.0, rapid_feedrate: 0.05}}
    initial_state: on_reference
{extra}
/x/plant:
  ros__parameters: {{model: first_order_velocity, gain: 10.3, time_constant: 0.040}}
/y/plant:
  ros__parameters: {{model: first_order_velocity, gain: 10.0, time_constant: 0.045}}
/x/servo:
  ros__parameters: {{law: pid_feedforward, kp: 8.08, ki: 93.2, kd: 0.24, gain: 10.3, time_constant: 0.040}}
/y/servo:
  ros__parameters: {{law: pid_feedforward, kp: 9.36, ki: 108.0, kd: 0.3, gain: 10.0, time_constant: 0.045}}
/contour_estimator:
  ros__parameters: {{type: newton, k_prime: 500.0, c_prime: 500.0, tolerance: 1.0e-9, max_iterations: 200}}
/ccc:
  ros__parameters: {{type: none}}
"""


def part(tmp_path, extra: str, name: str = "part.yaml"):
    (tmp_path / "part.ngc").write_text(PROGRAM)
    path = tmp_path / name
    path.write_text(EXPERIMENT.format(extra="\n".join(f"    {line}" for line in extra.splitlines())))
    return path


def run(path):
    experiment = load_experiment(path)
    loop = build_loop(experiment)
    return experiment, loop, simulate(loop)


def test_without_limits_the_arc_errs_most(tmp_path):
    from contouring_ros.records.blocks import block_results
    _, loop, result = run(part(tmp_path, ""))
    rows = block_results(loop.curve, result, loop.schedule)
    worst = {row.number: row.max_contour_error for row in rows}
    assert worst[30] > 3.3e-6 and max(v for n, v in worst.items() if n != 30) < 2.6e-6, worst
    assert loop.monitor is None and result.theta[-1] == loop.curve.domain[1]


def _path_motion(result, ts=1e-3):
    """Feed, acceleration and jerk along the path from the reference's arc length."""
    v = np.diff(result.theta) / ts
    a = np.diff(v) / ts
    return v, a, np.diff(a) / ts


def test_a_contour_breach_stops_on_the_path_in_its_block(tmp_path):
    experiment, loop, result = run(part(tmp_path, "contour_error_limit: 3.0e-6"))
    breach = loop.monitor.breach
    assert breach is not None and breach.what == "contour" and breach.error > 3.0e-6
    start = {b.line: b.start for b in loop.curve.blocks}
    assert start[5] <= breach.theta < start[6]                    # in N30, line 5
    message = breach_message(loop.curve, result, experiment)
    assert message.startswith("monitoring: contour error ") and "block N30 (line 5, G3)" in message
    assert "\n" not in message and "stopped on the path" in message
    # the reference decelerates along the path and rests there for the rest of the run
    k = breach.step + 2                                            # the first reference after the breach's
    v, a, jerk = _path_motion(result)
    assert np.all(v >= -1e-12) and v[k] > 0.0
    rest = np.flatnonzero(v > 0.0)[-1] + 1
    assert rest < len(result.time) - 100 and np.all(result.theta[rest:] == result.theta[rest])
    assert result.theta[rest] < loop.curve.domain[1]
    assert np.abs(a[k - 2:]).max() <= 1.0 * (1 + 1e-6) + 1e-9      # the plan's acceleration bound
    assert np.abs(jerk[k - 2:]).max() <= 10.0 * 1.05 + 1e-6        # and jerk (differences of a sampled profile)
    stop_time = (rest - k) * 1e-3
    assert stop_time < 0.2                                         # from 50 mm/s at 1 m/s^2 and 10 m/s^3
    # the scores end where the machine came to rest and the axes are in position there
    end = motion_steps(loop.curve, result, experiment)
    assert rest <= end - 1 <= rest + 50


def test_a_following_error_breach_names_the_axis(tmp_path):
    experiment, loop, result = run(part(tmp_path, "following_error_limit: [2.5e-6, 0.0]"))
    breach = loop.monitor.breach
    assert breach.what == 0 and abs(result.reference_position[breach.step, 0] - result.position[breach.step, 0]) \
        == breach.error > 2.5e-6
    assert "following error of axis x" in breach_message(loop.curve, result, experiment)
    assert "block N30 (line 5, G3)" in breach_message(loop.curve, result, experiment)


@pytest.mark.parametrize("extra, key", [("following_error_limit: [1.0e-5, 1.0e-5, 1.0e-5]", "following_error_limit"),
                                        ("contour_error_limit: -1.0e-5", "contour_error_limit")])
def test_bad_limits_are_refused_in_one_line(tmp_path, extra, key):
    with pytest.raises(ConfigError) as error:
        load_experiment(part(tmp_path, extra))
    assert key in str(error.value) and "\n" not in str(error.value)


def test_limits_need_a_planned_tool_path(tmp_path):
    text = (CONFIG / "paper000_b_ismc_h50_newton.yaml").read_text().replace(
        "sample_time:", "contour_error_limit: 1.0e-5\n    sample_time:")
    path = tmp_path / "parabola.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as error:
        load_experiment(path)
    assert "contour_error_limit" in str(error.value) and "tool path" in str(error.value)


def test_simulate_exits_non_zero_with_one_line(tmp_path):
    path = part(tmp_path, "contour_error_limit: 3.0e-6")
    done = subprocess.run([sys.executable, "-m", "contouring_ros.cli", "simulate", str(path)], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 1, done.stderr
    errors = [line for line in done.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "block N30 (line 5, G3)" in errors[0] and "Traceback" not in done.stderr
    assert "travel time" in done.stdout                  # the scores of the run up to the stop come first


@pytest.mark.graph
@pytest.mark.slow
def test_the_graph_stops_as_the_simulation_does_and_keeps_the_bag_whole(tmp_path, capsys):
    from conftest import assert_graph_equals_simulation
    from contouring_ros.cli import main
    path = part(tmp_path, "contour_error_limit: 3.0e-6\nfollowing_error_limit: [0.0, 6.0e-6]\nduration: 3.0")
    bag = tmp_path / "monitored.mcap"
    with pytest.raises(SystemExit) as exit_status:
        main(["run", str(path), "--bag", str(bag)])
    assert exit_status.value.code == 1
    errors = [line for line in capsys.readouterr().err.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "monitoring: contour error" in errors[0] and "block N30 (line 5, G3)" in errors[0]
    assert f"(bag {bag}, complete)" in errors[0]
    assert_graph_equals_simulation(path, bag)                     # bit for bit, and the bag reads whole
    recorded = read_run(bag)
    assert recorded.complete_steps == load_experiment(path).n_steps
    _, loop, result = run(path)
    assert loop.monitor.breach is not None
    assert errors[0] == "error: " + breach_message(loop.curve, result, recorded.experiment) + f" (bag {bag}, complete)"
