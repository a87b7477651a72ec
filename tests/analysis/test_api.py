"""The Python API of the README runs as written, and gives the numbers the CLI gives."""
import re

import numpy as np
import pytest

import contouring_ros as cr
from contouring_ros.records.bag_writer import write_simulation
from contouring_ros.config import build_loop
from contouring_ros.core.simulation import simulate
from contouring_ros.records.scoring import score_run
from conftest import DEFAULT, ROOT


def test_the_readme_example_runs(monkeypatch):
    readme = (ROOT / "README.md").read_text()
    block = re.search(r"## Python API.*?```python\n(.*?)```", readme, re.S)
    assert block, "the README has a Python API section with a python block"
    monkeypatch.chdir(ROOT)
    namespace = {}
    exec(compile(block.group(1), "README.md", "exec"), namespace)
    assert namespace["rows"][0].scores is not None


def test_simulate_and_read_bag_agree_with_the_core(tmp_path):
    experiment = cr.load_experiment(DEFAULT)
    run = cr.simulate(experiment, {"duration": 0.3})
    loop = build_loop(run.experiment)
    expected = simulate(loop)
    np.testing.assert_array_equal(run.result.position, expected.position)
    assert run.scores(0.1) == score_run(loop.curve, expected, 0.1)
    bag = write_simulation(tmp_path / "run.mcap", run.experiment, run.result)
    recorded = cr.read_bag(bag)
    assert recorded.axes == ["x", "y"] and recorded.scores().mce == run.scores().mce
    assert recorded.exact_contour_error().max() == pytest.approx(run.scores().mce, rel=1e-12)
    assert set(recorded.table()) >= {"time_s", "exact_contour_error_m", "command_y"}


def test_dir_shows_the_api_before_it_is_imported():
    """dir(contouring_ros) (what completion lists) names the API's functions in a fresh interpreter, and
    asking for it imports nothing of the API (the nodes start without numpy's API stack)."""
    import subprocess
    import sys
    script = ("import sys, contouring_ros as cr; names = dir(cr)\n"
              "assert 'contouring_ros.api' not in sys.modules\n"
              "print(' '.join(names))\n")
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert result.returncode == 0, result.stderr
    names = result.stdout.split()
    assert {"simulate", "load_experiment", "read_bag", "sweep_grid", "simulate_passes", "Run"} <= set(names)
    assert names == sorted(names)
