"""Realtime overrun policy: a node (or the composed loop) that falls more than max_lag behind its ticks stops
the run in one line naming it, its lag and the step (on_overrun: stop), or skips to the tick now due and
reports the skipped ticks (on_overrun: skip). The overrun is forced with the documented rehearsal knob
CONTOURING_ROS_SLOW_TICK, which makes /x/servo's every tick 2 ms longer than a 1 ms period allows."""
import re

import pytest

from contouring_ros.errors import RunError
from contouring_ros.run.runner import run_graph
from conftest import DEFAULT, shortened

pytestmark = [pytest.mark.graph, pytest.mark.slow]


#: s from launch to tick 0 for the process layout here: nine Python processes on a loaded 2-core machine can
#: take longer than the runner's 5 s to come up, which is an overrun of its own (tested below)
PROCESS_START_DELAY = 12.0


def _start_delay(layout, monkeypatch):
    if layout == "process":
        monkeypatch.setattr("contouring_ros.run.runner.REALTIME_START_DELAY", PROCESS_START_DELAY)


def _realtime(tmp_path, extra: str = "") -> object:
    path = tmp_path / "realtime.yaml"
    path.write_text(shortened(DEFAULT, 0.5).replace("    duration: 0.5\n",
                                                    "    duration: 0.5\n    timing: realtime\n" + extra))
    return path


@pytest.mark.parametrize("layout,culprit", [("process", "/x/servo fell"),
                                            ("composed", "the composed loop fell")])
def test_overrun_stops_the_run_in_one_line(layout, culprit, tmp_path, monkeypatch):
    from mcap.reader import make_reader
    monkeypatch.setenv("CONTOURING_ROS_SLOW_TICK", "/x/servo=0.002")
    _start_delay(layout, monkeypatch)
    bag = tmp_path / "overrun.mcap"
    with pytest.raises(RunError) as info:
        run_graph(_realtime(tmp_path), bag, layout=layout)
    message = str(info.value)
    assert "\n" not in message
    assert re.search(culprit + r" \d+\.\d ms behind its ticks at step \d+ \(max_lag 20 ms", message), message
    assert "the machine cannot keep up" in message
    if layout == "composed":
        assert "most work per tick: /x/servo" in message
    # the recorder closed the bag: it has its summary and the steps recorded until the trip
    with open(bag, "rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None and summary.statistics.message_count > 0


@pytest.mark.parametrize("layout", ["process", "composed"])
def test_overrun_skip_completes_and_reports_the_skipped_ticks(layout, tmp_path, monkeypatch):
    from contouring_ros.records.bag_reader import node_reports
    from contouring_ros.records.scoring import format_realtime, miss_rate
    monkeypatch.setenv("CONTOURING_ROS_SLOW_TICK", "/x/servo=0.002")
    _start_delay(layout, monkeypatch)
    bag = run_graph(_realtime(tmp_path, "    on_overrun: skip\n"), tmp_path / "skip.mcap", layout=layout)
    reports = node_reports(bag)
    servo = reports["/x/servo"]
    assert int(servo["skipped ticks"]) > 0
    assert int(servo["ticks"]) + int(servo["skipped ticks"]) <= 501
    assert miss_rate(servo) > 0.0
    assert float(servo["work p50 [us]"]) >= 2000.0
    assert "skipped ticks" in format_realtime(reports)


def test_a_graph_up_after_its_start_time_trips_at_once(tmp_path, monkeypatch):
    """Tick 0 already past when the loop starts (here: a start time 0.2 s after launch, before the composed
    process is up): the run stops at its first tick, saying so, instead of catching up late ticks."""
    monkeypatch.setattr("contouring_ros.run.runner.REALTIME_START_DELAY", 0.2)
    with pytest.raises(RunError, match=r"the composed loop came up \d+\.\d+ s after its first tick at step 0 "
                                       r"\(start_time; max_lag 20 ms\): the machine was too busy"):
        run_graph(_realtime(tmp_path), tmp_path / "late.mcap", layout="composed")


def test_overrun_keys_are_validated():
    from contouring_ros.config import parse_experiment
    from contouring_ros.errors import ConfigError
    text = DEFAULT.read_text()
    for extra, expected in (("max_lag: 0.0", "max_lag: expected a positive value"),
                            ("on_overrun: ignore", "on_overrun: expected one of")):
        with pytest.raises(ConfigError) as info:
            parse_experiment(text.replace("    sample_time: 0.001\n", f"    sample_time: 0.001\n    {extra}\n", 1),
                             "exp.yaml")
        assert expected in str(info.value) and "\n" not in str(info.value)
    experiment = parse_experiment(text, "exp.yaml")
    assert (experiment.max_lag, experiment.on_overrun) == (0.02, "stop")


def test_slow_tick_knob_names_nodes(monkeypatch):
    from contouring_ros.nodes.realtime import SLOW_TICK_ENV, slow_tick_seconds
    monkeypatch.setenv(SLOW_TICK_ENV, "x/servo=0.002, /ccc=0.001")
    assert slow_tick_seconds("/x/servo") == 0.002
    assert slow_tick_seconds("/ccc") == 0.001
    assert slow_tick_seconds("/y/servo") == 0.0


def test_a_node_up_after_the_run_s_last_tick_gives_up(tmp_path):
    """A node that comes up after the realtime run's end waits no longer for the rest of the graph (nodes
    that already finished never come back): one line, exit 1, long before graph_timeout."""
    import subprocess
    import sys
    import time
    from contouring_ros.run.runner import DomainLease, private_environment
    path = _realtime(tmp_path)
    with DomainLease() as lease:
        start = time.monotonic()
        done = subprocess.run([sys.executable, "-m", "contouring_ros.nodes.servo", "--ros-args", "-r", "__ns:=/x",
                               "--params-file", str(path), "-p", f"start_time:={time.time() - 60.0!r}"],
                              env=private_environment(lease.domain_id), capture_output=True, text=True, timeout=120)
    assert done.returncode == 1 and time.monotonic() - start < 60.0
    assert "error: /x/servo: the graph was not up by the realtime run's last tick" in done.stderr


def test_a_start_delay_longer_than_the_stall_timeout_is_not_a_stall(tmp_path, monkeypatch):
    """The process layout's recorder is up seconds before tick 0 and hears nothing until then: its stall clock
    starts at tick 0, so a stall_timeout shorter than the start delay still records the whole run."""
    from contouring_ros.records.bag_reader import node_reports
    _start_delay("process", monkeypatch)
    bag = run_graph(_realtime(tmp_path, "    stall_timeout: 2.0\n"), tmp_path / "quiet.mcap", layout="process")
    reports = node_reports(bag)
    assert int(reports["/x/servo"]["ticks"]) >= 499
