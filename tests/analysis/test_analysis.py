"""Analysis of bags without ROS: other writers, truncated files, replay, comparisons (figures:
test_figures.py; playback: graph/test_playback.py)."""
import json
import subprocess
import sys

import numpy as np
import pytest

from contouring_ros.records.comparison import compare_table
from contouring_ros.records.replay import replay_estimators
from contouring_ros.records.bag_writer import write_simulation
from contouring_ros.config import build_loop, parse_experiment
from contouring_ros.core.simulation import simulate
from contouring_ros.records.scoring import read_run, score_bag, score_run
from conftest import CONFIG, DEFAULT, ROOT, shortened


def _simulated(text: str):
    experiment = parse_experiment(text, "experiment")
    loop = build_loop(experiment)
    return experiment, loop, simulate(loop)


@pytest.fixture(scope="module")
def short_bag(tmp_path_factory):
    experiment, loop, result = _simulated(shortened(DEFAULT, 0.5))
    path = write_simulation(tmp_path_factory.mktemp("bags") / "short.mcap", experiment, result)
    return path, score_run(loop.curve, result)


def test_scoring_imports_no_ros(short_bag):
    path, expected = short_bag
    script = ("import sys, json; sys.modules['rclpy'] = None\n"
              "from contouring_ros.records.scoring import score_bag\n"
              f"print(json.dumps(score_bag({str(path)!r})[0].as_dict()))")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout) == json.loads(json.dumps(expected.as_dict()))


def test_bag_from_another_writer_scores_the_same(tmp_path):
    """A bag laid out like rosbag2's (mcap_ros2 writer, dict messages, no experiment stored)."""
    from mcap_ros2.writer import Writer
    from contouring_ros.wire import graph
    from contouring_ros.records.bag_writer import message_definition
    text = shortened(DEFAULT, 0.3)
    experiment, loop, result = _simulated(text)
    axes = list(experiment.axes)
    path = tmp_path / "rosbag2_like.mcap"
    with open(path, "wb") as stream:
        writer = Writer(stream)
        schemas = {name: writer.register_msgdef(name, message_definition(name)) for name in (
            "sensor_msgs/msg/JointState", "trajectory_msgs/msg/JointTrajectory")}

        def header(k):
            return {"stamp": {"sec": 0, "nanosec": k * 1_000_000}, "frame_id": ""}

        def state(k, names, position=(), velocity=(), effort=()):
            return {"header": header(k), "name": names, "position": list(position), "velocity": list(velocity),
                    "effort": list(effort)}
        for k in range(len(result.time)):
            t = k * 1_000_000
            point = {"positions": [*result.reference_position[k], result.theta[k]],
                     "velocities": [*result.reference_velocity[k], 0.0],
                     "accelerations": [*result.reference_acceleration[k], 0.0], "effort": [],
                     "time_from_start": {"sec": 0, "nanosec": t}}
            writer.write_message(graph.REFERENCE, schemas["trajectory_msgs/msg/JointTrajectory"],
                                 {"header": header(k), "joint_names": axes + ["theta"], "points": [point]}, t, t)
            for i, axis in enumerate(axes):
                writer.write_message(graph.state_topic(axis), schemas["sensor_msgs/msg/JointState"],
                                     state(k, [axis], [result.position[k, i]], [result.velocity[k, i]]), t, t)
                writer.write_message(graph.command_topic(axis), schemas["sensor_msgs/msg/JointState"],
                                     state(k, [axis], effort=[result.command[k, i]]), t, t)
            writer.write_message(graph.CONTOUR_ERROR, schemas["sensor_msgs/msg/JointState"],
                                 state(k, graph.estimate_names(axes), [*result.estimate_vector[k],
                                       result.estimate_signed[k], result.estimate_theta[k]]), t, t)
            writer.write_message(graph.CORRECTION, schemas["sensor_msgs/msg/JointState"],
                                 state(k, axes, effort=result.correction[k]), t, t)
        writer.finish()
    with pytest.raises(Exception, match="holds no experiment"):
        score_bag(path)
    scores, run = score_bag(path, experiment_text=text)
    assert scores == score_run(loop.curve, result)
    np.testing.assert_array_equal(run.result.position, result.position)


def test_truncated_bag_scores_up_to_its_last_chunk(tmp_path):
    experiment, loop, result = _simulated(shortened(DEFAULT, 2.0))
    path = write_simulation(tmp_path / "full.mcap", experiment, result)
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    run = read_run(cut)
    assert run.warnings and "last complete chunk" in run.warnings[0]
    steps = run.complete_steps
    assert 0 < steps < len(result.time)
    np.testing.assert_array_equal(run.result.position, result.position[:steps])
    scores, _ = score_bag(cut)
    expected = score_run(loop.curve, type(result)(**{k: v[:steps] for k, v in vars(result).items()}))
    assert scores == expected


def test_compare_gives_ratios_to_the_baseline(short_bag):
    path, expected = short_bag
    table = compare_table([("base", expected), ("other", expected)], 0)
    assert "ratio to base:" in table
    ratio_lines = table.split("ratio to base:")[1].strip().splitlines()[1:]
    assert all(line.split()[-2:] == ["1", "1"] for line in ratio_lines if "deviation" not in line)


@pytest.mark.graph
def test_replayed_newton_tracks_exact_error_better_than_recorded_tangent_line(tmp_path, write_experiment):
    text = shortened(CONFIG / "paper000_b_ismc_h100_vgccc.yaml", 0.6).replace(
        "initial_state: on_reference", "initial_state: at_rest")   # mm tracking errors from the start
    from contouring_ros.run.runner import run_graph
    bag = run_graph(write_experiment(text), tmp_path / "tangent.mcap")
    run = read_run(bag)
    exact, replays = replay_estimators(run, [{"type": "newton", "k_prime": 500.0, "c_prime": 500.0}])
    recorded, newton = replays
    assert recorded.name.startswith("recorded (tangent_line")
    assert np.abs(run.result.reference_position - run.result.position).max() > 1e-3
    assert newton.deviation_max < 0.2 * recorded.deviation_max
    assert newton.deviation_rms < recorded.deviation_rms



def test_replaying_the_recorded_estimator_s_type_changes_only_the_keys_given(tmp_path):
    """`replay BAG --estimator newton:k_prime=800` (the command's own example) on a Newton run takes the
    recorded section with k_prime changed (was: 'newton.c_prime: missing required key'); the same gains as
    recorded replay the recorded estimate."""
    from contouring_ros.records.replay import parse_estimator_spec
    from contouring_ros.records.bag_writer import write_simulation
    from contouring_ros.config import build_loop, parse_experiment
    from contouring_ros.core.simulation import simulate
    experiment = parse_experiment(shortened(DEFAULT, 0.2), "default")
    bag = write_simulation(tmp_path / "newton.mcap", experiment, simulate(build_loop(experiment)))
    run = read_run(bag)
    _, (recorded, same, stiffer) = replay_estimators(run, [parse_estimator_spec("newton"),
                                                           parse_estimator_spec("newton:k_prime=800")])
    assert same.name == "newton" and stiffer.name == "newton k_prime=800"
    np.testing.assert_allclose(same.estimate, recorded.estimate, rtol=1e-9, atol=1e-15)
    assert not np.allclose(stiffer.estimate, recorded.estimate, rtol=1e-9, atol=1e-15)
