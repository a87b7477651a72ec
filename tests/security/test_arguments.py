"""Every numeric option is checked against its stated range before any work, and replay refuses what it
cannot do in bounded time: one line and exit 2 each."""
import subprocess
import sys
import time

import pytest

from contouring_ros.wire import cdr
from contouring_ros.cli import main

from conftest import DEFAULT, ROOT

CENTURY_NS = 100 * 365 * 86400 * 10**9


@pytest.fixture(autouse=True)
def no_work(monkeypatch):
    """A refusal happens before any work: no pool may start (a --workers 100000 that got through would fork
    that many processes)."""
    from contouring_ros.studies import executors

    def refuse(*args, **kwargs):
        raise AssertionError("a process pool was started")
    monkeypatch.setattr(executors, "ProcessPoolExecutor", refuse)


@pytest.mark.parametrize("argv, option", [
    (["sweep", str(DEFAULT), "--grid", "ccc.kp=1,2", "--workers", "-1"], "--workers"),
    (["sweep", str(DEFAULT), "--grid", "ccc.kp=1,2", "--workers", "100000"], "--workers"),
    (["sweep", str(DEFAULT), "--grid", "ccc.kp=1,2", "--batch", "0"], "--batch"),
    (["sweep", str(DEFAULT), "--grid", "ccc.kp=1,2", "--from", "1e300"], "--from"),
    (["paper", "000", "--workers", "0"], "--workers"),
    (["benchmark", "--draws", "1000000000"], "--draws"),
    (["benchmark", "--searches", "1000000000"], "--searches"),
    (["benchmark", "--budget", "1e9"], "--budget"),
    (["benchmark", "--workers", "-1"], "--workers"),
    (["replay", str(DEFAULT), "--play", "--start", "1e300"], "--start"),
    (["replay", str(DEFAULT), "--play", "--wait-subscribers", "-5"], "--wait-subscribers"),
    (["replay", str(DEFAULT), "--play", "--wait-timeout", "1e12"], "--wait-timeout"),
    (["replay", str(DEFAULT), "--play", "--rate", "1e-300"], "--rate"),
    (["plot", str(DEFAULT), "--magnification", "-3"], "--magnification"),
])
def test_a_numeric_option_out_of_its_range_is_one_line(capsys, argv, option):
    with pytest.raises(SystemExit) as info:          # at parsing: before any work
        main(argv)
    err = capsys.readouterr().err
    assert info.value.code == 2 and err.count("\n") == 1 and f"argument {option}: expected" in err, err


def _bag(path, topic="/x/state", times=(0, 1_000_000)):
    """A bag of JointState messages on ``topic`` logged at ``times`` (ns)."""
    from mcap.writer import Writer
    payload = cdr.encode_joint_state(0, 0, ["x"], [0.0], [0.0], [])
    with open(path, "wb") as stream:
        writer = Writer(stream)
        writer.start("ros2", "test")
        schema = writer.register_schema("sensor_msgs/msg/JointState", "ros2msg", b"")
        channel = writer.register_channel(topic, "cdr", schema)
        for t in times:
            writer.add_message(channel, t, payload, t)
        writer.finish()
    return path


def _play(path, *options, timeout=60):
    from contouring_ros.run.runner import DomainLease, private_environment
    with DomainLease() as lease:
        return subprocess.run([sys.executable, "-m", "contouring_ros.cli", "replay", str(path), "--play",
                               "--wait-subscribers", "0", *options], env=private_environment(lease.domain_id),
                              capture_output=True, text=True, cwd=ROOT, timeout=timeout)


def test_replay_refuses_a_start_beyond_the_bag_and_a_topic_name_ros_refuses(tmp_path, capsys):
    short = _bag(tmp_path / "short.mcap")
    assert main(["replay", str(short), "--play", "--start", "5"]) == 2
    err = capsys.readouterr().err
    assert err == "error: --start 5: beyond the bag, whose last message is at 0.001 s after its first\n", err
    long_name = _bag(tmp_path / "long.mcap", topic="/" + "a" * 260)
    assert main(["replay", str(long_name), "--play"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "ROS refuses the name" in err and "(261 characters)" in err, err


def test_replay_says_and_refuses_a_gap_of_a_century_instead_of_waiting_it(tmp_path):
    path = _bag(tmp_path / "century.mcap", times=(0, 1_000_000, CENTURY_NS))
    started = time.monotonic()
    done = _play(path, "--rate", "1")
    assert done.returncode == 2 and time.monotonic() - started < 60
    last = done.stderr.strip().splitlines()
    assert len(last) == 1 and "over the 3600 s the player waits for one (published 2 messages" in last[0], \
        done.stderr
