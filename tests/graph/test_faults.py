"""Faults: dead, frozen or killed nodes, signals to the runner, bad values, divergence, windup, cross-talk."""
import os
import re
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from contouring_ros.config import build_loop, load_experiment, parse_experiment
from contouring_ros.core.curves import Circle
from contouring_ros.core.estimators import BranchCheck, NewtonEstimator
from contouring_ros.core.interpolation import UniformSchedule, reference
from contouring_ros.core.simulation import simulate
from contouring_ros.errors import RunError
from contouring_ros.run.runner import DomainLease, run_graph
from contouring_ros.run.shared_memory import shared_memory_in_use
from contouring_ros.records.scoring import read_run, score_bag, score_run
from conftest import DEFAULT, ROOT, machine_pace, recorded_bytes, shortened, sigint_as_from_a_terminal

graph = pytest.mark.graph


def _node_processes(marker: str) -> list:
    out = subprocess.run(["pgrep", "-f", marker], capture_output=True, text=True)
    return [int(pid) for pid in out.stdout.split()]


def _run_and_signal(experiment, bag, node_name, sig, after: float, domain_id: int | None = None):
    """Run the graph (on ``domain_id``, else a free one); ``after`` seconds into the lockstep send ``sig`` to
    ``node_name``. Returns the RunError and the seconds from the signal to the runner's report."""
    sent = {}

    def started(nodes):
        target = next(node for node in nodes if node.name == node_name)

        def send():
            deadline = time.monotonic() + 30
            while recorded_bytes(bag) < 2000:     # lockstep under way
                if time.monotonic() > deadline:
                    return
                time.sleep(0.05)
            time.sleep(after)
            sent["time"] = time.monotonic()
            target.process.send_signal(sig)
        threading.Thread(target=send, daemon=True).start()

    with pytest.raises(RunError) as info:
        run_graph(experiment, bag, on_started=started, domain_id=domain_id)
    return info.value, time.monotonic() - sent["time"]


@graph
def test_killed_node_stops_the_run_and_the_bag_scores_up_to_the_failure(tmp_path):
    bag = tmp_path / "killed.mcap"
    shared_memory_before = _shared_memory_files()
    with DomainLease() as lease:
        domain = lease.domain_id
    error, delay = _run_and_signal(DEFAULT, bag, "/y/servo", signal.SIGKILL, 0.5, domain)
    # the killed node could not release its Fast DDS segments: the runner removed them
    assert not _leaked_shared_memory(shared_memory_before, [domain])
    assert "/y/servo was killed by SIGKILL" in str(error)
    assert delay < 1.0 + 5.5        # noticed within a second; the rest get SIGINT and up to 5 s to close
    run = read_run(bag)
    assert not run.warnings                          # the recorder closed the bag with its summary
    assert 0 < run.complete_steps < load_experiment(DEFAULT).n_steps
    scores, _ = score_bag(bag)
    assert np.isfinite(scores.mce)


@graph
def test_killed_recorder_leaves_a_readable_bag(tmp_path):
    bag = tmp_path / "recorder.mcap"
    error, _ = _run_and_signal(DEFAULT, bag, "/recorder", signal.SIGKILL, 1.0)
    assert "/recorder was killed by SIGKILL" in str(error)
    assert "readable up to its last complete chunk" in str(error)
    run = read_run(bag)
    assert run.warnings and "last complete chunk" in run.warnings[0]
    assert run.complete_steps > 0
    assert np.isfinite(score_bag(bag)[0].mce)


@graph
def test_frozen_node_gives_a_stall_error_naming_node_and_topic(tmp_path, write_experiment):
    path = write_experiment(shortened(DEFAULT, 2.0).replace("    sample_time: 0.001\n",
                                                            "    sample_time: 0.001\n    stall_timeout: 2.0\n", 1))
    error, delay = _run_and_signal(path, tmp_path / "stall.mcap", "/x/servo", signal.SIGSTOP, 0.3)
    # the nodes downstream of the frozen servo stall first: its plant (no /x/command), then the estimator (no
    # /x/state); on a busy machine the CCC's consumers may report first (no /contour_error, /ccc/correction)
    downstream = ("/x/command", "/x/state", "/contour_error", "/ccc/correction")
    assert "stalled" in str(error) and any(topic in str(error) for topic in downstream), str(error)
    # stall timeout, then up to 5 s for the frozen node to take SIGKILL, and the machine's pace
    assert delay < 2.0 + 5.0 + 2.0 * machine_pace()


@graph
def test_a_run_past_its_timeout_names_each_node_still_running_with_its_last_line(tmp_path, write_experiment):
    from contouring_ros.wire import graph as graph_names
    path = write_experiment(shortened(DEFAULT, 5.0))
    with pytest.raises(RunError) as raised:
        run_graph(path, tmp_path / "late.mcap", timeout=1.0)
    message = str(raised.value)
    assert message.startswith("the run did not finish within 1 s (still running: ") and "\n" not in message, message
    running = re.findall(r"(/[\w/]+), its last line: ", message)
    assert running and set(running) <= set(graph_names.node_names(["x", "y"])), message
    # the error names the bag where the recorder got to write one (moved into place as the run ended)
    late = tmp_path / "late.mcap"
    assert raised.value.bag == (late if late.is_file() else None)


@graph
@pytest.mark.parametrize("sig,name", [(signal.SIGTERM, "SIGTERM"), (signal.SIGINT, "SIGINT")])
def test_signal_to_the_runner_stops_every_node_and_closes_the_bag(tmp_path, write_experiment, sig, name):
    from mcap.reader import make_reader
    path = write_experiment(DEFAULT.read_text(), f"signal_{name}.yaml")
    bag = tmp_path / "signal.mcap"
    runner = subprocess.Popen([sys.executable, "-m", "contouring_ros.cli", "run", str(path), "--bag", str(bag)],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
                              preexec_fn=sigint_as_from_a_terminal)
    deadline = time.monotonic() + 30
    while recorded_bytes(bag) < 2000 and time.monotonic() < deadline:
        time.sleep(0.05)
    runner.send_signal(sig)
    _, err = runner.communicate(timeout=30)
    assert runner.returncode != 0
    assert f"interrupted by {name}" in err and "Traceback" not in err
    assert _node_processes(str(path)) == []
    with open(bag, "rb") as stream:
        assert make_reader(stream).get_summary() is not None


# a servo whose command overflows; divergence_factor 0 lets the positions run away until the values are not
# finite, so that the nodes' own input checks (not the divergence check) stop or hold the run
UNSTABLE = DEFAULT.read_text().replace("    a: 12.5\n    b: 12.5\n", "    a: 1.0e+9\n    b: 12.5\n", 1).replace(
    "    sample_time: 0.001\n", "    sample_time: 0.001\n    divergence_factor: 0.0\n", 1)


@graph
def test_non_finite_values_are_rejected_and_stop_the_run(tmp_path, write_experiment):
    path = write_experiment(shortened_text(UNSTABLE, 1.0))
    with pytest.raises(RunError, match="rejected .* non-finite value") as info:
        run_graph(path, tmp_path / "nan.mcap")
    assert "step" in str(info.value)


@graph
def test_non_finite_values_held_when_configured(tmp_path, write_experiment):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    text = shortened_text(UNSTABLE, 1.0).replace("    sample_time: 0.001\n",
                                                 "    sample_time: 0.001\n    on_invalid_input: hold\n", 1)
    bag = run_graph(write_experiment(text), tmp_path / "hold.mcap")
    rejected = 0
    with open(bag, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for _, _, _, msg in reader.iter_decoded_messages(topics=["/diagnostics"]):
            rejected += sum(int(v.value) for v in msg.status[0].values if v.key.startswith("rejected"))
    assert rejected > 0


def shortened_text(text: str, duration: float) -> str:
    return text.replace("    sample_time: 0.001\n", f"    sample_time: 0.001\n    duration: {duration}\n", 1)


def test_newton_branch_check_recovers_from_the_far_side_of_a_circle():
    # Paper 000 Fig. 3: from theta_hat = 0 a point on the opposite side of the circle sees theta = 0 as a
    # stationary point (the farthest one); the local Newton flow stays there.
    circle = Circle(0.05)
    ref = reference(circle, UniformSchedule(0.0, 1.0, 1.0), 0.0)
    far_point = np.array([-0.0501, 0.0])
    plain = NewtonEstimator(circle, 500.0, 500.0, 0.0, inner_step=0.001)
    checked = NewtonEstimator(circle, 500.0, 500.0, 0.0, inner_step=0.001,
                              branch_check=BranchCheck(circle, 256, 1e-4))
    assert np.linalg.norm(plain.step(ref, far_point).vector) > 0.09
    estimate = checked.step(ref, far_point)
    assert np.linalg.norm(estimate.vector) == pytest.approx(1e-4, abs=1e-7)
    assert checked.recoveries == 1
    checked.step(ref, far_point)
    assert checked.recoveries == 1      # on the right branch now: no further restarts


def test_saturated_servo_does_not_wind_up():
    text = shortened_text(DEFAULT.read_text(), 0.6).replace("    initial_state: on_reference",
                                                           "    initial_state: at_rest")
    pid_x = ("    law: pid_feedforward\n    kp: 8.08\n    ki: 93.2\n    kd: 0.24\n    gain: 10.3\n"
             "    time_constant: 0.040\n    output_limit: 2.0e-3\n")
    start = text.index("/x/servo:\n  ros__parameters:\n") + len("/x/servo:\n  ros__parameters:\n")
    text = text[:start] + pid_x + text[text.index("\n/y/servo:"):]
    text = text.replace("    disturbance: {type: constant, value: 1.5e-4}\n",
                        "    disturbance: {type: constant, value: 1.5e-4}\n    saturation: 2.0e-3\n", 1)
    loop = build_loop(parse_experiment(text, "saturated"))
    servo = loop.servos[0]
    integrals, commands = [], []
    original = servo.step

    def recording_step(*args):
        command = original(*args)
        integrals.append(servo.pid.integral)
        commands.append(command)
        return command
    servo.step = recording_step
    result = simulate(loop)
    commands, integrals = np.array(commands), np.array(integrals)
    saturated = np.abs(commands) >= 2.0e-3
    assert saturated.sum() > 10                       # the limit is hit from rest
    growth = np.diff(np.abs(integrals))[saturated[1:]]
    assert np.all(growth <= 1e-15)                    # no integration into the limit
    assert np.all(np.isfinite(result.position))


def test_domain_leases_are_exclusive():
    with DomainLease(77) as first:
        with pytest.raises(RunError, match="ROS domain 77 is held by another run"):
            DomainLease(77)
        with pytest.raises(RunError, match="ROS domain 77 is held by another run"):
            DomainLease(77, shared=True)                  # a private run's domain is never shared
        with DomainLease() as other:
            assert other.domain_id != first.domain_id
    with DomainLease(77):
        pass


def test_shared_leases_share_a_domain_and_keep_private_runs_out():
    """--domain: runs sharing one domain (each under its own namespace) hold it together; a run picking a
    free private domain never lands there while they do."""
    with DomainLease(78, shared=True), DomainLease(78, shared=True):
        with pytest.raises(RunError, match="ROS domain 78 is held by another run"):
            DomainLease(78)
        assert all(DomainLease().domain_id != 78 for _ in range(30))


@graph
def test_two_experiments_at_once_do_not_hear_each_other(tmp_path, write_experiment):
    paths = [write_experiment(shortened(DEFAULT, 0.5), "a.yaml"),
             write_experiment(shortened(DEFAULT.parent / "paper000_b_ismc_h50_vgccc.yaml", 0.5), "b.yaml")]
    bags, errors = {}, []

    def run(path):
        try:
            bags[path] = run_graph(path, tmp_path / f"{path.stem}.mcap")
        except Exception as error:  # reported below
            errors.append(error)
    threads = [threading.Thread(target=run, args=(path,)) for path in paths]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert not errors
    for path in paths:
        loop = build_loop(load_experiment(path))
        expected = simulate(loop)
        recorded = read_run(bags[path]).result
        np.testing.assert_array_equal(recorded.position, expected.position)


def _shared_memory_files() -> set:
    return {name for name in os.listdir("/dev/shm") if "fastrtps" in name or "fastdds" in name} \
        if os.path.isdir("/dev/shm") else set()


def _port_domain(name: str) -> int | None:
    """The ROS domain of a Fast DDS shared-memory port file (``fastrtps_port<N>[_el|_mutex]``): its port
    number N is a UDP-style port, 7400 + 250 x domain + offset (offsets below 250); None for other files."""
    match = re.fullmatch(r"fastrtps_port(\d+)(_.*)?", name)
    return (int(match.group(1)) - 7400) // 250 if match else None


def _leaked_shared_memory(before: set, domains) -> set:
    """Fast DDS port files in /dev/shm that were not there ``before``, belong to the ROS ``domains`` this
    test's runs used and no live process uses: a participant of these runs left behind (a participant's
    port file stays when it cannot release its segments). Files of another Fast DDS program running
    beside the suite, on other domains, are no leak of ours; segment files named at random cannot be told
    apart, so they are not judged."""
    new = {name for name in _shared_memory_files() - before if _port_domain(name) in set(domains)}
    if not new:
        return set()
    used, leaked = {os.path.basename(path) for path in shared_memory_in_use()}, set()
    for name in new - used:
        try:
            if os.stat(f"/dev/shm/{name}").st_uid == os.getuid():
                leaked.add(name)
        except OSError:
            continue
    return leaked


def test_soak_in_process_50_runs_identical():
    experiment = load_experiment(DEFAULT)
    scores = set()
    for _ in range(50):
        loop = build_loop(experiment)
        scores.add(score_run(loop.curve, simulate(loop)))
    assert len(scores) == 1


@graph
@pytest.mark.slow
def test_soak_graph_10_runs_identical_and_nothing_leaked(tmp_path, write_experiment):
    path = write_experiment(shortened(DEFAULT, 1.0), "soak.yaml")
    before_shm = _shared_memory_files()
    scores, domains = set(), []
    for i in range(10):
        with DomainLease() as lease:           # a free domain, then held by the run itself
            domains.append(lease.domain_id)
        bag = run_graph(path, tmp_path / f"soak{i}.mcap", domain_id=domains[-1])
        scores.add(score_bag(bag)[0])
    assert len(scores) == 1
    assert _node_processes(str(path)) == []
    assert not _leaked_shared_memory(before_shm, domains)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["soak.yaml"] + [f"soak{i}.mcap" for i in range(10)])


@graph
def test_a_node_alone_waits_graph_timeout_then_names_what_it_waited_for(tmp_path, write_experiment):
    """Hand-started nodes wait ``graph_timeout`` (default 300 s) for the rest of the graph, and log it."""
    from contouring_ros.run.runner import private_environment
    path = write_experiment(shortened(DEFAULT, 0.1).replace("    sample_time: 0.001\n",
                                                            "    sample_time: 0.001\n    graph_timeout: 1.5\n", 1))
    with DomainLease() as domain:
        started = time.monotonic()
        out = subprocess.run([sys.executable, "-m", "contouring_ros.nodes.plant", "--ros-args", "-r", "__ns:=/x",
                              "--params-file", str(path)], env=private_environment(domain.domain_id), capture_output=True,
                             text=True, timeout=60, cwd=ROOT)
    assert out.returncode == 1 and time.monotonic() - started < 30
    assert "/x/plant: the graph did not come up within 1.5 s (graph_timeout; still waiting for" in out.stderr
    assert "waiting up to 1.5 s (graph_timeout)" in out.stderr      # logged through rclpy


@pytest.mark.graph
def test_a_node_waiting_for_its_graph_stops_at_once_on_sigterm():
    """A node started by hand waits up to graph_timeout (300 s) for the rest of the graph; SIGTERM (or its
    runner dying, through the parent-death signal) must still stop it within seconds, not at the timeout."""
    from contouring_ros.run.runner import private_environment
    with DomainLease() as lease:
        node = subprocess.Popen([sys.executable, "-m", "contouring_ros.nodes.plant", "--ros-args", "-r", "__ns:=/x",
                                 "-r", "__node:=plant", "--params-file", str(DEFAULT)],
                                env=private_environment(lease.domain_id), stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True)
        try:
            for line in node.stdout:                   # up and waiting
                if "waiting up to" in line:
                    break
            node.send_signal(signal.SIGTERM)
            started = time.monotonic()
            node.wait(timeout=60)
        finally:
            node.kill()
    assert time.monotonic() - started < 10 and node.returncode != 0
