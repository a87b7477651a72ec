"""Every shipped scenario runs through the node graph (composed layout: the same nodes and lockstep, in one
process) and reproduces its in-process simulation exactly, cut to its first 60 steps."""
import numpy as np
import pytest

from contouring_ros.config import build_loop, load_experiment
from contouring_ros.core.simulation import simulate
from contouring_ros.run.runner import run_graph
from contouring_ros.records.scoring import read_run
from conftest import CONFIG, shortened

pytestmark = [pytest.mark.graph, pytest.mark.slow]
SIGNALS = ["theta", "reference_position", "reference_velocity", "reference_acceleration", "position", "velocity",
           "estimate_theta", "estimate_vector", "estimate_signed", "correction", "command"]


@pytest.mark.parametrize("scenario", sorted(p.name for p in CONFIG.glob("*.yaml")))
def test_scenario_through_the_graph_equals_the_simulation(scenario, tmp_path):
    path = tmp_path / scenario
    path.write_text(shortened(CONFIG / scenario, 0.06))
    bag = run_graph(path, tmp_path / "run.mcap", layout="composed")
    loop = build_loop(load_experiment(path))
    expected = simulate(loop)
    recorded = read_run(bag)
    assert recorded.complete_steps == loop.n_steps
    for name in SIGNALS:
        np.testing.assert_array_equal(getattr(recorded.result, name), getattr(expected, name), err_msg=name)
