"""Intruders: peers that publish junk, wrong names, other stamps or a second stream on the graph's topics,
and the runner's lifecycle (SIGKILL of the runner, a double Ctrl-C). No node or recorder may crash with a
traceback, every event is on /diagnostics or in the runner's one-line error, and no run exits 0 with a
polluted or short bag."""
import os
import signal
import subprocess
import sys
import time
from types import SimpleNamespace

import numpy as np
import pytest

from contouring_ros.wire import cdr
from contouring_ros.wire import graph as graph_module
from contouring_ros.config import build_loop, load_experiment
from contouring_ros.core.simulation import simulate
from contouring_ros.errors import RunError
from contouring_ros.run.runner import DomainLease, private_environment, run_graph
from contouring_ros.records.scoring import read_run
from conftest import DEFAULT, ROOT, recorded_bytes, shortened, sigint_as_from_a_terminal

graph = pytest.mark.graph

INTRUDER = r'''
import sys, time, os
import rclpy
from contouring_ros.wire import cdr
from contouring_ros.nodes.base import DIAGNOSTICS_QOS, GRAPH_QOS, message_class
from contouring_ros.run.runner import recording_path
topic, type_name, mode, bag = sys.argv[1:5]
bag = str(recording_path(bag))                         # the recorder's file while the run lasts
rclpy.init()
node = rclpy.create_node("intruder")
pub = node.create_publisher(message_class(type_name), topic, DIAGNOSTICS_QOS if topic == "/diagnostics" else GRAPH_QOS)
deadline = time.monotonic() + 60
while (not os.path.exists(bag) or os.path.getsize(bag) < 2000) and time.monotonic() < deadline:
    time.sleep(0.02)                                   # lockstep under way
while pub.get_subscription_count() < 1 and time.monotonic() < deadline:
    time.sleep(0.01)
if mode == "short":
    payloads = [b"\x00\x01\x00\x00"]
elif mode == "negative":
    from diagnostic_msgs.msg import DiagnosticArray
    array = DiagnosticArray()
    array.header.stamp.sec = -5
    payloads = [array]
elif mode == "names":
    payloads = [cdr.encode_joint_state(0, 0, ["q"], effort=[0.0])]
elif mode == "second":
    payloads = [cdr.encode_joint_state(0, 1_000_000 * k, ["x"], effort=[1.0]) for k in range(1, 5)]
elif mode == "stamps":      # duplicate and past steps, then far-future ones
    payloads = [cdr.encode_joint_state(0, 0, ["x"], [0.0], [0.0]), cdr.encode_joint_state(0, 1_000_000, ["x"], [0.0], [0.0])]
    payloads += [cdr.encode_joint_state(2, 500_000_000 + 1_000_000 * k, ["x"], [0.0], [0.0]) for k in range(20)]
for payload in payloads:
    pub.publish(payload)
pub.wait_for_all_acked(rclpy.duration.Duration(seconds=2))
time.sleep(0.5)
'''


def _run_with_intruder(path, bag, topic, type_name, mode):
    """Run the graph on a private domain with an intruder publishing ``mode`` payloads on ``topic``; return
    (bag or RunError, the intruder's output)."""
    with DomainLease() as lease:
        domain = lease.domain_id
    intruder = subprocess.Popen([sys.executable, "-c", INTRUDER, topic, type_name, mode, str(bag)], cwd=ROOT,
                                env=private_environment(domain), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                text=True)
    try:
        try:
            outcome = run_graph(path, bag, domain_id=domain)
        except RunError as error:
            outcome = error
    finally:
        out, _ = intruder.communicate(timeout=60)
    return outcome, out


def _diagnostics(bag) -> list:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    with open(bag, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        return [status.message for _, _, _, msg in reader.iter_decoded_messages(topics=["/diagnostics"])
                for status in msg.status]


@pytest.fixture
def experiment(write_experiment):
    return write_experiment(shortened(DEFAULT, 3.0))


@graph
@pytest.mark.parametrize("topic,type_name,mode,expected", [
    ("/x/state", "sensor_msgs/msg/JointState", "short", "rejected /x/state"),
    ("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray", "negative", "rejected /diagnostics: negative stamp"),
    ("/x/command", "sensor_msgs/msg/JointState", "names", "rejected /x/command: a message from an unexpected"),
    ("/x/command", "sensor_msgs/msg/JointState", "second", "rejected /x/command: a message from an unexpected"),
])
def test_an_intruder_stops_the_run_in_one_line_without_a_traceback(tmp_path, experiment, topic, type_name, mode,
                                                                   expected):
    bag = tmp_path / f"{mode}.mcap"
    outcome, _ = _run_with_intruder(experiment, bag, topic, type_name, mode)
    assert isinstance(outcome, RunError), "a run with an intruder exited 0"
    text = str(outcome)
    assert expected in text and "Traceback" not in text and "struct.error" not in text
    run = read_run(bag)                                     # closed with its summary, and short
    assert not run.warnings and run.complete_steps < load_experiment(experiment).n_steps
    # the event is in the runner's one-line error (the node that refused reports it on /diagnostics too,
    # which the recorder may not take before it is stopped)


@graph
def test_past_duplicate_and_far_future_stamps_are_held_out_and_reported(tmp_path, write_experiment):
    text = shortened(DEFAULT, 3.0).replace("    sample_time: 0.001\n",
                                           "    sample_time: 0.001\n    on_invalid_input: hold\n", 1)
    path = write_experiment(text)
    bag = tmp_path / "stamps.mcap"
    outcome, out = _run_with_intruder(path, bag, "/x/state", "sensor_msgs/msg/JointState", "stamps")
    # a second writer on a graph topic: its messages numbered as the genuine writer's would be cannot be told
    # apart with certainty, so under hold the run completes but does not end 0, and says why
    assert isinstance(outcome, RunError), "a run that saw a second publisher ended 0"
    assert "a second publisher of /x/state appeared" in str(outcome) and "\n" not in str(outcome), outcome
    # nothing of the intruder's is in the bag here: it equals the in-process simulation
    recorded = read_run(bag).result
    expected = simulate(build_loop(load_experiment(path)))
    np.testing.assert_array_equal(recorded.position, expected.position)
    messages = _diagnostics(bag)
    assert any("rejected /x/state" in message for message in messages)


def _fake_node(timing="lockstep", n_steps=100, next_step=10):
    from contouring_ros.nodes.node import LockstepNode
    topics = {t.name: t for t in graph_module.recorded_topics(["x", "y"])}
    fake = SimpleNamespace(_topics=topics, _sequence={"/x/state": 1}, _last_step={"/x/state": -1},
                           sample_time_ns=1_000_000, n_steps=n_steps, next_step=next_step,
                           _realtime=timing == "realtime")
    fake.stamp_problem = lambda *a: LockstepNode.stamp_problem(fake, *a)
    return fake, lambda data, seq: LockstepNode.intake_problem(fake, "/x/state", data, seq)


def test_intake_refuses_short_foreign_past_duplicate_off_step_and_far_future_messages():
    fake, intake = _fake_node()
    state = lambda ns: cdr.encode_joint_state(0, ns, ["x"], [0.0], [0.0])  # noqa: E731
    assert "4-byte payload" in intake(b"\x00\x01\x00\x00", 1)
    assert intake(state(10_000_000), 1) is None
    assert "unexpected publisher" in intake(state(11_000_000), 1)           # another writer's first message
    assert "repeats or precedes" in intake(state(10_000_000), 2)            # duplicate
    assert "repeats or precedes" in intake(state(5_000_000), 2)             # past
    assert "not on a step" in intake(state(11_500_000), 2)
    assert "too far ahead" in intake(state(90_000_000), 2)                  # bounded pending buffer
    assert "past the run's last step" in intake(cdr.encode_joint_state(1, 0, ["x"], [0.0], [0.0]), 2)
    assert "negative stamp" in intake(cdr.encode_joint_state(-1, 0, ["x"], [0.0], [0.0]), 2)
    assert intake(state(11_000_000), 2) is None and fake._sequence["/x/state"] == 3


def test_wrong_joint_names_are_a_message_problem():
    topics = {t.name: t for t in graph_module.topics(["x", "y"])}
    good = cdr.decode_joint_state(cdr.encode_joint_state(0, 0, ["x"], effort=[1.0]))
    bad = cdr.decode_joint_state(cdr.encode_joint_state(0, 0, ["q"], effort=[1.0]))
    assert graph_module.message_problem(topics["/x/command"], good) is None
    assert "joint names ['q']" in graph_module.message_problem(topics["/x/command"], bad)


def _node_processes(marker: str) -> list:
    out = subprocess.run(["pgrep", "-f", marker], capture_output=True, text=True)
    return [int(pid) for pid in out.stdout.split() if int(pid) != os.getpid()]


def _start_runner(path, bag):
    runner = subprocess.Popen([sys.executable, "-m", "contouring_ros.cli", "run", str(path), "--bag", str(bag)],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
                              preexec_fn=sigint_as_from_a_terminal)
    deadline = time.monotonic() + 60
    while recorded_bytes(bag) < 2000 and time.monotonic() < deadline:
        time.sleep(0.05)
    return runner


def _domain_of(pid: int) -> int:
    environ = open(f"/proc/{pid}/environ", "rb").read().split(b"\0")
    return int(next(entry for entry in environ if entry.startswith(b"ROS_DOMAIN_ID=")).split(b"=")[1])


@graph
def test_sigkill_of_the_runner_takes_every_node_with_it_and_the_lock_until_they_are_gone(tmp_path, write_experiment):
    path = write_experiment(shortened(DEFAULT, 20.0), "orphans.yaml")
    runner = _start_runner(path, tmp_path / "orphans.mcap")
    nodes = [pid for pid in _node_processes(str(path)) if pid != runner.pid]
    assert nodes, "no node started"
    domain = _domain_of(nodes[0])
    runner.kill()
    runner.communicate(timeout=10)
    deadline = time.monotonic() + 10
    while True:
        try:
            with DomainLease(domain):
                alive = _node_processes(str(path))
                assert not alive, f"the domain lock was free while nodes {alive} still ran"
            break
        except RunError:
            pass                                              # held: nodes still running
        assert time.monotonic() < deadline, f"nodes still running 10 s after the runner: {_node_processes(str(path))}"
        time.sleep(0.05)
    assert _node_processes(str(path)) == []


@graph
def test_a_double_sigint_still_stops_every_node(tmp_path, write_experiment):
    path = write_experiment(shortened(DEFAULT, 20.0), "double.yaml")
    runner = _start_runner(path, tmp_path / "double.mcap")
    runner.send_signal(signal.SIGINT)
    time.sleep(0.05)
    runner.send_signal(signal.SIGINT)
    _, err = runner.communicate(timeout=30)
    assert runner.returncode != 0 and "Traceback" not in err, err
    deadline = time.monotonic() + 5
    while _node_processes(str(path)) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert _node_processes(str(path)) == []
