"""A diverging run is a result, not a crash: simulate stops it at the step that left its bounds and says so in
one line, sweeps go on and keep its row, and bags of it score and plot up to the step before."""
import subprocess
import sys

import numpy as np
import pytest

from contouring_ros.records.bag_writer import write_simulation
from contouring_ros.config import build_loop, parse_experiment
from contouring_ros.core.simulation import first_divergence, simulate
from contouring_ros.errors import BagError, Diverged
from contouring_ros.records.scoring import read_run
from contouring_ros.studies.sweep import run_sweep, write_sweep_csv
from conftest import CONFIG, ROOT, shortened

PIDFF = CONFIG / "paper000_a_pidff_h50_newton.yaml"


def _unstable(kp: str, duration: float = 0.5) -> str:
    return shortened(PIDFF, duration).replace("    kp: 8.08\n", f"    kp: {kp}\n")


def test_simulate_stops_at_the_first_step_out_of_bounds():
    loop = build_loop(parse_experiment(_unstable("100000"), "unstable"))
    with pytest.raises(Diverged) as caught:
        simulate(loop)
    error = caught.value
    message = str(error)
    assert message.startswith(f"diverged at t = {error.time:g} s (step {error.step}): an axis is ")
    assert "\n" not in message and "divergence_factor x the path's size" in message
    assert len(error.result.time) == error.step > 0
    assert np.all(np.isfinite(error.result.position))
    # the step it names is the first whose position is out of bounds: the same run without the check
    free = simulate(build_loop(parse_experiment(_unstable("100000"), "unstable")), stop_on_divergence=False)
    np.testing.assert_array_equal(free.position[:error.step], error.result.position)
    assert first_divergence(free.time, free.position, free.reference_position)[0] <= error.step + 1


def test_a_stable_run_is_not_called_diverged():
    loop = build_loop(parse_experiment(shortened(PIDFF, 0.5), "stable"))
    result = simulate(loop)
    assert first_divergence(result.time, result.position, result.reference_position) is None


def test_a_sweep_with_unstable_points_keeps_going_and_writes_every_row(tmp_path):
    rows = run_sweep(shortened(PIDFF, 0.4), {"x/servo.kp": [8.08, 9.0, 100000.0, 200000.0]}, workers=1)
    assert [row.settings["x/servo.kp"] for row in rows][-2:] == [100000.0, 200000.0]      # diverged: last
    assert all(row.scores is not None and row.failure == "" for row in rows[:2])
    assert all(row.scores is None and row.failure.startswith("diverged at t = ") for row in rows[2:])
    write_sweep_csv(rows, tmp_path / "sweep.csv", ["x", "y"])
    lines = (tmp_path / "sweep.csv").read_text().splitlines()
    assert len(lines) == 5 and "effort_rms_x" in lines[0] and "tracking_max_y_m" in lines[0] and "travel_time_s" in lines[0]
    assert lines[3].split(",")[2].startswith("diverged at t = ") or "diverged at t = " in lines[3]


def test_a_bag_of_a_diverged_run_scores_and_plots_up_to_the_step_before(tmp_path):
    experiment = parse_experiment(_unstable("100000"), "unstable")
    result = simulate(build_loop(experiment), stop_on_divergence=False)
    bag = write_simulation(tmp_path / "diverged.mcap", experiment, result)
    run = read_run(bag)
    assert any(w.startswith("the run diverged at t = ") for w in run.warnings)
    k = first_divergence(result.time, result.position, result.reference_position)[0]
    assert run.complete_steps == k
    for command in (["score", str(bag)], ["plot", str(bag), "--out", str(tmp_path / "plots")]):
        out = subprocess.run([sys.executable, "-m", "contouring_ros.cli", *command], capture_output=True,
                             text=True, cwd=ROOT)
        assert out.returncode == 0 and "Traceback" not in out.stderr, out.stderr
        assert "warning: the run diverged at t = " in out.stderr


def test_simulate_command_says_diverged_in_one_line(tmp_path):
    path = tmp_path / "unstable.yaml"
    path.write_text(_unstable("100000"))
    out = subprocess.run([sys.executable, "-m", "contouring_ros.cli", "simulate", str(path)], capture_output=True,
                         text=True, cwd=ROOT)
    assert out.returncode == 1 and out.stderr.startswith("error: diverged at t = ") and out.stderr.count("\n") == 1
    assert "scores of the" in out.stdout


def test_a_topic_without_messages_is_named_not_a_traceback(tmp_path, monkeypatch):
    """A bag whose /x/command channel exists but holds no message (a node that never published)."""
    from contouring_ros.records import bag_writer
    experiment = parse_experiment(shortened(PIDFF, 0.05), "short")
    result = simulate(build_loop(experiment))
    write = bag_writer.BagWriter.write
    monkeypatch.setattr(bag_writer.BagWriter, "write",
                        lambda self, topic, *args: None if topic == "/x/command" else write(self, topic, *args))
    path = write_simulation(tmp_path / "silent.mcap", experiment, result)
    monkeypatch.undo()
    with pytest.raises(BagError, match="no complete step: /x/command recorded no messages"):
        read_run(path)
    out = subprocess.run([sys.executable, "-m", "contouring_ros.cli", "score", str(path)], capture_output=True,
                         text=True, cwd=ROOT)
    assert out.returncode == 2 and out.stderr.count("\n") == 1 and "/x/command recorded no messages" in out.stderr


@pytest.mark.graph
def test_the_graph_stops_a_diverging_run_where_the_simulation_does(tmp_path):
    from contouring_ros.errors import RunError
    from contouring_ros.run.runner import run_graph
    path = tmp_path / "unstable.yaml"
    path.write_text(_unstable("1000", 1.2))
    with pytest.raises(Diverged) as simulated:
        simulate(build_loop(parse_experiment(path.read_text(), "unstable")))
    with pytest.raises(RunError) as error:
        run_graph(path, tmp_path / "run.mcap", layout="composed")
    assert f"/contour_estimator: {simulated.value}" in str(error.value)
    run = read_run(tmp_path / "run.mcap")
    assert run.complete_steps == simulated.value.step
    np.testing.assert_array_equal(run.result.position, simulated.value.result.position)
