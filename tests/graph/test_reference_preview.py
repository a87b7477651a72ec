"""The reference preview (docs/ARCHITECTURE.md, "Reference preview"): a ZPETC servo reads the reference ahead,
the interpolator publishes it with each /reference, the graph of separate processes reproduces the
simulation bit for bit, write_simulation writes the same /reference payloads, and a servo node that would
read further than the interpolator publishes refuses to start, naming the key."""
import subprocess
import sys

import numpy as np
import pytest
from mcap.reader import make_reader

from contouring_ros.wire import cdr
from contouring_ros.records.bag_writer import write_simulation
from contouring_ros.core.interpolation import reference
from contouring_ros.core.simulation import simulate
from contouring_ros.experiment.build import build_curve, build_loop, build_schedule
from contouring_ros.experiment.files import load_experiment
from contouring_ros.run.runner import DomainLease, private_environment, run_graph
from conftest import CONFIG, ROOT, assert_graph_equals_simulation, shortened

pytestmark = pytest.mark.graph


def _references(bag) -> list:
    with open(bag, "rb") as stream:
        return [message.data for _, channel, message in make_reader(stream).iter_messages(topics=["/reference"])]


def test_a_zpetc_graph_of_separate_processes_equals_the_simulation_and_carries_the_preview(tmp_path):
    path = tmp_path / "zpetc.yaml"
    path.write_text(shortened(CONFIG / "zpetc_ellipse.yaml", 0.08))
    bag = run_graph(path, tmp_path / "run.mcap", layout="process")
    assert_graph_equals_simulation(path, bag)
    experiment = load_experiment(path)
    messages = [cdr.decode_joint_trajectory(data) for data in _references(bag)]
    curve = build_curve(experiment)
    schedule = build_schedule(experiment, curve)
    for k, message in enumerate(messages[:40]):
        assert len(message.points) == 1 + 4        # command_delay 1 + 3
        for j, point in enumerate(message.points[1:], start=1):
            assert (point.time_from_start.sec, point.time_from_start.nanosec) == (0, j * 1_000_000)
            later = reference(curve, schedule, (k + j) * experiment.sample_time)
            np.testing.assert_allclose(point.positions[:2], later.position, rtol=0, atol=1e-15)
    written = write_simulation(tmp_path / "written.mcap", experiment, simulate(build_loop(experiment)))
    assert _references(written) == _references(bag)[:len(_references(written))]


def test_a_servo_node_refuses_a_preview_shorter_than_its_law_reads(tmp_path):
    with DomainLease() as lease:
        process = subprocess.run(
            [sys.executable, "-m", "contouring_ros.nodes.servo", "--ros-args", "--params-file",
             str(CONFIG / "zpetc_ellipse.yaml"), "-r", "__ns:=/x"],
            cwd=ROOT, env=private_environment(lease.domain_id), capture_output=True, text=True, timeout=60)
    out = process.stdout + process.stderr
    assert process.returncode == 1, out
    assert "reference_preview" in out and "reads 4 steps" in out and "Traceback" not in out, out


def test_an_mpcc_graph_of_separate_processes_equals_the_simulation(tmp_path):
    # the CCC node reads the horizon's reference from the preview points; the same QPs are solved in both
    text = shortened(CONFIG / "paper003_ellipse_natural_local_fn100.yaml", 0.06)
    text = text[:text.index("/ccc:")] + ("/ccc:\n  ros__parameters:\n    type: mpcc\n    mass: [1.0, 1.0]\n"
                                         "    damping: [798.5, 862.75]\n    gain: [16.23, 17.58]\n    horizon: 15\n"
                                         "    command_limit: [8.0]\n    disturbance_gain: 0.2\n")
    path = tmp_path / "mpcc.yaml"
    path.write_text(text)
    bag = run_graph(path, tmp_path / "run.mcap", layout="process")
    assert_graph_equals_simulation(path, bag)
    assert len(cdr.decode_joint_trajectory(_references(bag)[0]).points) == 1 + 15


def test_each_ilc_pass_through_the_graph_equals_its_simulated_pass(tmp_path):
    # pass 2 plays back the correction learned from pass 1's bag, read from the .npy beside its own bag
    from contouring_ros.studies.learning import run_passes, simulate_passes
    path = tmp_path / "ilc.yaml"
    # with measurement noise: pass 2 reads its own noise seed from the file the runner writes for it
    path.write_text(shortened(CONFIG / "ilc_ellipse.yaml", 0.05).replace("passes: 8", "passes: 2").replace(
        "    time_constant: 0.040\n", "    time_constant: 0.040\n    measurement_noise: 1.0e-6\n"))
    experiment = load_experiment(path)
    bags = run_passes(path, experiment, tmp_path / "run.mcap",
                      lambda config, bag, parsed: run_graph(config, bag, experiment=parsed, layout="composed"))
    assert [bag.name for bag in bags] == ["run_pass1.mcap", "run_pass2.mcap"]
    assert (tmp_path / "run_pass2_learned.npy").is_file()
    from contouring_ros.records.scoring import read_run
    for bag, (_, expected) in zip(bags, simulate_passes(experiment)):
        recorded = read_run(bag).result
        for name in ("position", "correction", "command"):
            np.testing.assert_array_equal(getattr(recorded, name), getattr(expected, name), err_msg=name)
    assert np.any(read_run(bags[1]).result.correction != 0.0)
    # `simulate --bag` writes each pass's bag with the graph's payloads on every topic
    from contouring_ros import cli
    assert cli.main(["simulate", str(path), "--bag", str(tmp_path / "sim.mcap")]) == 0
    for j, bag in enumerate(bags, 1):
        graph_payloads, simulated = (read_run(b, keep_payloads=True).payloads for b in (bag, tmp_path / f"sim_pass{j}.mcap"))
        assert set(graph_payloads) == set(simulated)
        assert all(graph_payloads[topic] == simulated[topic] for topic in graph_payloads), j


def test_a_reference_with_fewer_preview_points_than_read_stops_the_node_in_one_line():
    from types import SimpleNamespace
    from contouring_ros.errors import RunError
    from contouring_ros.nodes.node import LockstepNode
    message = cdr.decode_joint_trajectory(cdr.encode_joint_trajectory(
        0, 0, ["x", "y", "theta"], [0.0] * 3, [0.0] * 3, [0.0] * 3, preview=[((0, 1_000_000), [0.0] * 3)]))
    node = SimpleNamespace(name="/x/servo")
    assert len(LockstepNode.preview_points(node, 7, message, 1, "the zpetc law")) == 1
    with pytest.raises(RunError, match=r"^/x/servo: step 7: /reference carries 1 preview points; the zpetc law reads 4$"):
        LockstepNode.preview_points(node, 7, message, 4, "the zpetc law")
