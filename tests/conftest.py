"""Shared fixtures: experiment texts and paths."""
from __future__ import annotations

import json
import signal
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
CONFIG = ROOT / "config"
DEFAULT = CONFIG / "paper000_b_ismc_h50_newton.yaml"


def load_tool(name: str):
    """The module of the script tools/NAME.py (the tools are scripts, not a package)."""
    import importlib.util
    spec = importlib.util.spec_from_file_location(name, ROOT / "tools" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def machine_pace() -> float:
    """How much slower than an idle machine this one runs now: the 1-minute load average per core, at least
    1 and at most 8. Timeouts that a busy machine (other programs, other test jobs) would overrun are
    multiplied by it, so the tests judge function, not the machine's spare capacity."""
    import os
    try:
        load = os.getloadavg()[0] / (os.cpu_count() or 1)
    except OSError:
        return 1.0
    return min(max(load, 1.0), 8.0)


def shortened(path: Path, duration: float) -> str:
    """The experiment at ``path`` cut to ``duration`` seconds of its schedule."""
    text = path.read_text()
    return text.replace("    sample_time: 0.001\n", f"    sample_time: 0.001\n    duration: {duration}\n", 1)


def sigint_as_from_a_terminal():
    """``preexec_fn`` for a runner a test interrupts with SIGINT: SIGINT's default disposition, as a runner in a
    terminal's foreground has it, also when the test session itself runs in the background (where a
    non-interactive shell hands SIGINT on ignored, and a background runner rightly keeps ignoring it)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.fixture
def write_experiment(tmp_path):
    def write(text: str, name: str = "experiment.yaml") -> Path:
        path = tmp_path / name
        path.write_text(text)
        return path
    return write


def pytest_collection_modifyitems(config, items):
    """Graph tests run real processes over Fast DDS on a shared 2-core machine: a test that fails once is
    run once more, and the rerun is reported in the summary line ("N rerun") so it stays visible."""
    for item in items:
        if item.get_closest_marker("graph") is not None and item.get_closest_marker("flaky") is None:
            item.add_marker(pytest.mark.flaky(reruns=1))


def recorded_bag(folder: Path, duration: float, name: str) -> tuple:
    """The default experiment shortened to ``duration`` s, simulated and written as a bag in ``folder``:
    (result, path, the bag's bytes, (complete, chunks) of its summary)."""
    from contouring_ros.records import bag_reader, bag_writer
    from contouring_ros.config import build_loop, parse_experiment
    from contouring_ros.core.simulation import simulate
    experiment = parse_experiment(shortened(DEFAULT, duration), "short")
    result = simulate(build_loop(experiment))
    path = bag_writer.write_simulation(folder / name, experiment, result)
    data = path.read_bytes()
    with open(path, "rb") as stream:
        complete, chunks, _ = bag_reader.summary_chunks(stream, len(data), path, [])
    return result, path, data, (complete, chunks)



def recorded_bytes(bag) -> int:
    """How far a run's bag has got: the size of the file the recorder writes while the run lasts (beside the
    bag's name, :func:`contouring_ros.run.runner.recording_path`), or of the bag once moved into place."""
    from contouring_ros.run.runner import recording_path
    for path in (recording_path(bag), Path(bag)):
        try:
            return path.stat().st_size
        except OSError:
            continue
    return 0


def cli_with_file_size_limit(args, limit_bytes: int, cwd=ROOT):
    """The CLI with every file it writes capped at ``limit_bytes`` (RLIMIT_FSIZE: a write past it fails
    with EFBIG, as a full disk fails one with ENOSPC)."""
    import resource
    import subprocess
    import sys

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))
    return subprocess.run([sys.executable, "-m", "contouring_ros.cli", *args], cwd=cwd, capture_output=True,
                          text=True, preexec_fn=limit, timeout=300)


#: the signals of a run that the graph's bag and the in-process simulation must hold bit for bit alike
SIGNALS = ["theta", "reference_position", "reference_velocity", "position", "velocity", "estimate_theta",
           "estimate_vector", "estimate_signed", "correction", "command"]


def example_part_with_feed_events(folder: Path, events: list, name: str) -> Path:
    """The example part (config/gcode_example_part.yaml) shortened to 3 s with ``events`` as its feed_events,
    written to ``folder``/``name``.yaml with its part program's path made absolute."""
    text = shortened(CONFIG / "gcode_example_part.yaml", 3.0).replace(
        "sample_time: 0.001", f"sample_time: 0.001\n    feed_events: {json.dumps(events)}")
    assert "feed_events" in text
    path = folder / f"{name}.yaml"
    path.write_text(text.replace("file: parts/example_part.ngc", f"file: {CONFIG / 'parts/example_part.ngc'}"))
    return path


def assert_graph_equals_simulation(experiment_path, bag):
    """The bag of a lockstep graph run of ``experiment_path`` holds what the in-process simulation computes,
    bit for bit, and scores the same."""
    import numpy as np

    from contouring_ros.experiment.build import build_loop
    from contouring_ros.experiment.files import load_experiment
    from contouring_ros.core.simulation import simulate
    from contouring_ros.records.scoring import read_run, score_bag, score_run
    experiment = load_experiment(experiment_path)
    loop = build_loop(experiment)
    expected = simulate(loop)
    recorded = read_run(bag)
    assert recorded.complete_steps == loop.n_steps
    for name in SIGNALS + ["time", "reference_acceleration"]:
        np.testing.assert_array_equal(getattr(recorded.result, name), getattr(expected, name), err_msg=name)
    assert score_bag(bag)[0] == score_run(loop.curve, expected, experiment=experiment)
