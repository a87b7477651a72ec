"""Every interruption ends cleanly: a node in any state exits 130 on SIGINT and 143 on SIGTERM without a
traceback (the recorder's bag closed and readable), and the runner says what exists (the bag, or no bag
yet) and exits 130 (143 for SIGTERM). The recorder's progress, end-of-run count and refusals name the steps
it has recorded."""
import select
import signal
import subprocess
import sys
import time
from types import SimpleNamespace

import pytest

from contouring_ros.run.runner import DomainLease, private_environment
from conftest import DEFAULT, ROOT, recorded_bytes, shortened, sigint_as_from_a_terminal

graph = pytest.mark.graph


def _wait_for_line(process, fragment: str, timeout: float = 60.0) -> str:
    """Read the process's output until a line holds ``fragment``; return everything read."""
    seen, deadline = "", time.monotonic() + timeout
    while time.monotonic() < deadline:
        ready, _, _ = select.select([process.stdout], [], [], 0.5)
        if ready:
            line = process.stdout.readline()
            if not line:
                break
            seen += line
            if fragment in line:
                return seen
    raise AssertionError(f"no {fragment!r} in: {seen}")


@graph
@pytest.mark.parametrize("sig,code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
@pytest.mark.parametrize("node", ["plant", "recorder"])
def test_a_node_waiting_for_its_graph_stops_quietly(tmp_path, node, sig, code):
    """Started by hand, alone on its domain, the node waits for the rest of the graph; a signal then ends it
    with 130 or 143 and no traceback (was: RCLError 'publisher's context is invalid', exit 1)."""
    bag = tmp_path / "alone.mcap"
    arguments = ["--ros-args", "--params-file", str(DEFAULT)]
    arguments += ["-r", "__ns:=/x"] if node == "plant" else ["-p", f"bag:={bag}", "-p", f"experiment_file:={DEFAULT}"]
    with DomainLease() as lease:
        process = subprocess.Popen([sys.executable, "-m", f"contouring_ros.nodes.{node}", *arguments], cwd=ROOT,
                                   env=private_environment(lease.domain_id), stdout=subprocess.PIPE,
                                   stderr=subprocess.STDOUT, text=True)
        try:
            seen = _wait_for_line(process, "for the rest of the graph")
            time.sleep(0.3)
            process.send_signal(sig)
            out, _ = process.communicate(timeout=30)
        finally:
            if process.poll() is None:
                process.kill()
    assert process.returncode == code, seen + out
    assert "Traceback" not in seen + out and "RCLError" not in seen + out, seen + out
    if node == "recorder":
        from mcap.reader import make_reader
        with open(bag, "rb") as stream:
            assert make_reader(stream).get_summary() is not None     # closed with its summary


@graph
@pytest.mark.parametrize("moment", ["at once", "while recording"])
@pytest.mark.parametrize("sig,code,name", [(signal.SIGINT, 130, "SIGINT"), (signal.SIGTERM, 143, "SIGTERM")])
def test_the_runner_says_what_exists_and_exits_130(tmp_path, write_experiment, moment, sig, code, name):
    """At once (before the recorder opened the bag, or just after) and while recording: the runner exits 130
    (143), and says the bag holds the steps recorded so far only where a readable bag is there."""
    from contouring_ros.errors import BagError
    from contouring_ros.records.scoring import read_run
    path = write_experiment(shortened(DEFAULT, 3.0), f"interrupted_{name}.yaml")
    bag = tmp_path / "interrupted.mcap"
    runner = subprocess.Popen([sys.executable, "-m", "contouring_ros.cli", "run", str(path), "--bag", str(bag)],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
                              preexec_fn=sigint_as_from_a_terminal)
    if moment == "at once":
        _wait_for_line(runner, "starting")
        time.sleep(0.2)
    else:
        deadline = time.monotonic() + 60
        while recorded_bytes(bag) < 2000 and time.monotonic() < deadline:
            time.sleep(0.05)
    runner.send_signal(sig)
    out, err = runner.communicate(timeout=60)
    assert runner.returncode == code, err
    assert f"interrupted by {name}: stopped every node; " in err and "Traceback" not in err, err
    if "holds the steps recorded so far" in err:
        try:
            read_run(bag)
        except BagError as error:       # a bag from before the first step: readable, with nothing to score
            assert "no " in str(error), error
    else:
        assert "no bag yet" in err and not bag.exists(), err
    if moment == "while recording":
        assert "holds the steps recorded so far" in err and "partial bag" in out, (out, err)


def test_the_recorder_counts_the_steps_it_has_recorded():
    """Its progress and end-of-run count are the steps every lockstep topic has recorded (was: 'step 0 of
    2001', 'completed 0 steps', whatever it recorded), in lockstep and in realtime timing."""
    from contouring_ros.nodes.recorder import RecorderNode
    recorder = object.__new__(RecorderNode)
    recorder.lockstep_topics = ["/reference", "/x/state", "/x/command"]
    recorder.counts = {"/reference": 3001, "/x/state": 3001, "/x/command": 3000, "/diagnostics": 4}
    recorder._last_step = {"/reference": 3000, "/x/state": 2998, "/x/command": 3000, "/diagnostics": 0}
    recorder.experiment = SimpleNamespace(timing="lockstep")
    assert recorder.current_step() == 3000
    recorder.experiment = SimpleNamespace(timing="realtime")
    assert recorder.current_step() == 2999


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_landing_where_python_ignores_exceptions_still_interrupts_the_run(sig):
    """A signal that arrives in code whose exceptions Python ignores (here a finaliser; in a run, logging's
    at-fork lock release while a node is started) is not lost: the runner's handler only notes it, and the
    next check raises it. With Python's own SIGINT handler the KeyboardInterrupt died in the finaliser and
    the run went on to exit 0."""
    import os
    from contouring_ros.run import interruptions

    class SignalledWhileFinalised:
        def __del__(self):
            os.kill(os.getpid(), sig)
            for _ in range(1000):       # the handler runs between bytecodes, here inside the finaliser
                pass

    previous = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        replaced = interruptions.note_interruptions()
        try:
            SignalledWhileFinalised()       # dropped at once: __del__ runs, its exceptions are ignored
            with pytest.raises(interruptions.Terminated) as raised:
                interruptions.raise_pending_termination()
            assert raised.value.signum == sig
        finally:
            for s, handler in replaced.items():
                signal.signal(s, handler)
            interruptions.TERMINATIONS.clear()
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def test_an_ignored_sigint_stays_ignored_during_a_run():
    """A runner started in the background by a shell without job control ignores SIGINT; the run keeps it so."""
    from contouring_ros.run import interruptions
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        replaced = interruptions.note_interruptions()
        try:
            assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
            assert signal.SIGTERM in replaced
        finally:
            for s, handler in replaced.items():
                signal.signal(s, handler)
    finally:
        signal.signal(signal.SIGINT, previous)
