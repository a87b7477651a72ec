"""`replay --play`: every message reaches a reliable subscriber, topic and start filters, loop, Ctrl-C,
and a bag cannot make the player import code."""
import json
import os
import select
import signal
import subprocess
import sys

import pytest

from contouring_ros.wire import graph
from contouring_ros.records.bag_writer import write_simulation
from contouring_ros.config import build_loop, parse_experiment
from contouring_ros.core.simulation import simulate
from contouring_ros.run.playback import UnplayableType, installed_message_class
from conftest import DEFAULT, ROOT, shortened

# A subscriber in its own process: subscribes (raw) to the topics given as JSON {topic: type}, with a
# reliable keep-all QoS, or keep-last of the given depth, or the default QoS ("default": reliable, depth
# 10); prints "ready", then once it has `expected` messages on every topic, or once no message came for
# `quiet` seconds after the first, {topic: [count, first stamp in ns]} (the stamp a message starts with:
# header.stamp, or Clock.clock); and "reached" as soon as it has `mark` messages in all.
LISTENER = """
import json, struct, sys, time, importlib, rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy, HistoryPolicy
topics, qos_name, expected, quiet = json.loads(sys.argv[1]), sys.argv[2], int(sys.argv[3]), float(sys.argv[4])
mark = int(sys.argv[5])
if qos_name == 'keep_all':
    qos = QoSProfile(depth=0, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_ALL)
elif qos_name == 'default':
    qos = 10
else:
    qos = QoSProfile(depth=int(qos_name), reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
rclpy.init(); node = rclpy.create_node('listener'); got = {t: 0 for t in topics}; first = {}; last = [None]
def counter(topic):
    def count(message):
        if not got[topic]:
            sec, nanosec = struct.unpack_from('<iI', message, 4)
            first[topic] = sec * 10**9 + nanosec
        got[topic] += 1; last[0] = time.monotonic()
        if sum(got.values()) == mark:
            print('reached', flush=True)
    return count
for topic, type_name in topics.items():
    package, _, name = type_name.split('/')
    cls = getattr(importlib.import_module(package + '.msg'), name)
    node.create_subscription(cls, topic, counter(topic), qos, raw=True)
print('ready', flush=True)
deadline = time.monotonic() + 60
while min(got.values()) < expected and time.monotonic() < deadline:
    rclpy.spin_once(node, timeout_sec=0.05)
    if last[0] is not None and time.monotonic() - last[0] > quiet:
        break
print(json.dumps({t: [got[t], first.get(t)] for t in topics}), flush=True)
"""


def _simulated(text: str):
    experiment = parse_experiment(text, "experiment")
    loop = build_loop(experiment)
    return experiment, simulate(loop)


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    """A 0.5 s run as the recorder writes it: 500 messages on every topic, /clock included."""
    experiment, result = _simulated(shortened(DEFAULT, 0.5))
    path = write_simulation(tmp_path_factory.mktemp("bags") / "short.mcap", experiment, result)
    return path, len(result.time)


@pytest.fixture
def domain():
    from contouring_ros.run.runner import DomainLease, private_environment
    with DomainLease() as lease:
        yield private_environment(lease.domain_id)


def _listen(env, topics: dict, qos: str = "keep_all", expected: int = 10**9, quiet: float = 2.0, mark: int = -1):
    listener = subprocess.Popen([sys.executable, "-c", LISTENER, json.dumps(topics), qos, str(expected),
                                 str(quiet), str(mark)], env=env, stdout=subprocess.PIPE, text=True)
    assert listener.stdout.readline().strip() == "ready"
    return listener


def _play(env, path, *options, timeout=60):
    return subprocess.run([sys.executable, "-m", "contouring_ros.cli", "replay", str(path), "--play", *options],
                          env=env, capture_output=True, text=True, cwd=ROOT, timeout=timeout)


def _heard(listener) -> dict:
    """{topic: (messages, first stamp in ns)} of a listener."""
    return {topic: tuple(value) for topic, value in json.loads(listener.communicate(timeout=70)[0]).items()}


def _counts(listener) -> dict:
    return {topic: count for topic, (count, _) in _heard(listener).items()}


STATE_AND_CLOCK = {"/x/state": "sensor_msgs/msg/JointState", graph.CLOCK: "rosgraph_msgs/msg/Clock"}


@pytest.mark.graph
@pytest.mark.parametrize("qos", ["keep_all", "10000"])
def test_every_message_reaches_a_reliable_subscriber_at_rate_0(bag, domain, qos):
    """No pause before publishing: the player waits for the subscriber to match, then keeps every topic
    within its acknowledgement window."""
    path, steps = bag
    topics = {t.name: t.type for t in graph.topics(["x", "y"]) if t.name != graph.DIAGNOSTICS}
    listener = _listen(domain, topics, qos, expected=steps)
    play = _play(domain, path, "--rate", "0")
    assert play.returncode == 0, play.stderr
    assert f"published {steps * len(topics)} messages" in play.stdout
    assert _counts(listener) == {topic: steps for topic in topics}


@pytest.mark.graph
def test_default_qos_subscriber_gets_the_first_messages_at_real_time(bag, domain):
    """The player waits for the subscriber to match: the messages of t = 0 reach it. (Whether a depth-10
    subscriber keeps up with 1 kHz topics afterwards is up to its CPU, so the count is not checked.)"""
    path, steps = bag
    listener = _listen(domain, STATE_AND_CLOCK, "default", expected=steps, quiet=1.0)
    play = _play(domain, path, "--rate", "1")
    assert play.returncode == 0, play.stderr
    assert "warning" not in play.stdout
    heard = _heard(listener)
    assert {topic: first for topic, (_, first) in heard.items()} == {topic: 0 for topic in STATE_AND_CLOCK}


@pytest.mark.graph
def test_topics_and_start_filter(bag, domain):
    path, steps = bag
    listener = _listen(domain, {**STATE_AND_CLOCK, "/y/state": "sensor_msgs/msg/JointState"}, quiet=1.0)
    play = _play(domain, path, "--rate", "0", "--topics", "/x/state", "--start", "0.2")
    assert play.returncode == 0, play.stderr
    kept = sum(1 for k in range(steps) if k * 1_000_000 >= 200_000_000)      # stamps t_k = k ms
    assert f"published {kept} messages" in play.stdout
    # /clock is made up from the played messages' times, /y/state is not played
    assert _counts(listener) == {"/x/state": kept, graph.CLOCK: kept, "/y/state": 0}


def test_unknown_topic_is_refused_in_one_line(bag):
    path, _ = bag
    play = _play(dict(os.environ), path, "--topics", "/x/state,/nowhere", "--wait-subscribers", "0")
    assert play.returncode == 2
    assert play.stderr.count("\n") == 1 and "/nowhere" in play.stderr and "/x/state" in play.stderr


@pytest.mark.graph
def test_no_subscriber_is_waited_for_a_bounded_time_and_said(bag, domain):
    path, steps = bag
    play = _play(domain, path, "--rate", "0", "--topics", "/x/state", "--wait-timeout", "0.5")
    assert play.returncode == 0, play.stderr
    assert ("warning: 0 of 1 subscriber after 0.5 s; publishing anyway (early messages may be lost)"
            in play.stdout.splitlines())
    assert f"published {steps} messages" in play.stdout


@pytest.mark.graph
def test_loop_repeats_until_ctrl_c(bag, domain):
    path, steps = bag
    listener = _listen(domain, {"/x/state": "sensor_msgs/msg/JointState"}, quiet=3.0, mark=2 * steps + 1)
    play = subprocess.Popen([sys.executable, "-m", "contouring_ros.cli", "replay", str(path), "--play", "--rate",
                             "0", "--loop", "--topics", "/x/state"], env=domain, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:                      # Ctrl-C once the listener has the third pass under way
        assert select.select([listener.stdout], [], [], 30)[0] and listener.stdout.readline() == "reached\n"
    finally:
        play.send_signal(signal.SIGINT)
    out, err = play.communicate(timeout=20)
    assert play.returncode == 130, (out, err)
    assert "Traceback" not in err and "stopped (Ctrl-C): published" in out, (out, err)
    published = int(out.split("stopped (Ctrl-C): published ")[1].split()[0])
    assert published > 2 * steps
    # the player waits briefly for the messages under way at the Ctrl-C: a keep-all subscriber has them all
    assert _counts(listener)["/x/state"] == published, out


EVIL_MODULE = """
import pathlib
pathlib.Path({marker!r}).write_text("ran")
class msg:
    Boom = None
"""


def _crafted_bag(path, type_names):
    """A bag whose channels name these types (the payload is a real JointState)."""
    from contouring_ros.wire import cdr
    payload = cdr.encode_joint_state(0, 0, ["x"], [0.0], [0.0], [])
    with open(path, "wb") as stream:
        from mcap.writer import Writer
        writer = Writer(stream)
        writer.start("ros2", "test")
        for i, type_name in enumerate(type_names, start=1):
            schema = writer.register_schema(type_name, "ros2msg", b"")
            channel = writer.register_channel(f"/crafted{i}", "cdr", schema)
            for k in range(3):
                writer.add_message(channel, k * 1_000_000, payload, k * 1_000_000)
        writer.finish()
    return path


@pytest.mark.parametrize("type_name", ["pwn_me/msg/Boom", "pwn_me.msg", "os/msg/system", "pwn_me/msg/../Boom",
                                       "sensor_msgs/msg/NoSuchType", "pwn_me/srv/Boom"])
def test_a_type_outside_the_installed_message_packages_is_refused_without_import(tmp_path, monkeypatch, type_name):
    marker = tmp_path / "marker"
    package = tmp_path / "mods" / "pwn_me"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text(EVIL_MODULE.format(marker=str(marker)))
    (package / "msg.py").write_text(EVIL_MODULE.format(marker=str(marker)))
    monkeypatch.syspath_prepend(str(tmp_path / "mods"))
    with pytest.raises(UnplayableType):
        installed_message_class(type_name)
    assert not marker.exists() and "pwn_me" not in sys.modules


def test_a_package_shadowing_an_installed_one_is_not_imported(tmp_path, monkeypatch):
    """stereo_msgs is installed (and registered), but a directory earlier on sys.path holds another
    stereo_msgs: the one found is not under the prefix of the index, so it is refused, not imported."""
    marker = tmp_path / "marker"
    (tmp_path / "mods" / "stereo_msgs").mkdir(parents=True)
    (tmp_path / "mods" / "stereo_msgs" / "__init__.py").write_text(EVIL_MODULE.format(marker=str(marker)))
    monkeypatch.syspath_prepend(str(tmp_path / "mods"))
    monkeypatch.delitem(sys.modules, "stereo_msgs", raising=False)
    with pytest.raises(UnplayableType, match="not the one installed"):
        installed_message_class("stereo_msgs/msg/DisparityImage")
    assert not marker.exists() and "stereo_msgs" not in sys.modules


def test_installed_message_types_resolve():
    from sensor_msgs.msg import JointState
    assert installed_message_class("sensor_msgs/msg/JointState") is JointState
    assert installed_message_class("rosgraph_msgs/msg/Clock").__name__ == "Clock"


def test_a_crafted_bag_is_refused_topic_by_topic_and_runs_no_code(tmp_path, bag):
    """The player in its own process, with the crafted module importable: the topic is refused in one line
    and the module never runs; a bag with nothing else to play is refused as a whole."""
    marker = tmp_path / "marker"
    mods = tmp_path / "mods"
    (mods / "pwn_me").mkdir(parents=True)
    (mods / "pwn_me" / "__init__.py").write_text(EVIL_MODULE.format(marker=str(marker)))
    crafted = _crafted_bag(tmp_path / "crafted.mcap", ["pwn_me/msg/Boom", "sensor_msgs/msg/JointState"])
    from contouring_ros.run.runner import DomainLease, private_environment
    with DomainLease() as lease:
        env = {**private_environment(lease.domain_id), "PYTHONPATH": str(mods)}
        play = _play(env, crafted, "--rate", "0", "--wait-subscribers", "0")
    assert play.returncode == 0, play.stderr
    refusals = [line for line in play.stdout.splitlines() if "refusing" in line]
    assert refusals == [("warning: refusing /crafted1: type 'pwn_me/msg/Boom': "
                         "not a message of an installed ROS interface package")]
    assert "published 3 messages" in play.stdout
    only_evil = _crafted_bag(tmp_path / "only_evil.mcap", ["pwn_me/msg/Boom"])
    play = _play(env, only_evil, "--wait-subscribers", "0")
    assert play.returncode == 2 and "nothing to play" in play.stderr
    assert not marker.exists()
