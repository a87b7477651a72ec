"""The compiled kernels (contouring_ros/core/kernels.py, numba where installed) give the pure path's runs bit for bit."""
from pathlib import Path

import numpy as np
import pytest
import yaml

from contouring_ros.config import build_loop
from contouring_ros.core import kernels
from contouring_ros.core.batch import simulate_batch
from contouring_ros.core.simulation import simulate
from contouring_ros.sweep import combinations
from contouring_ros.tuning import REALISTIC

CONFIG = Path(__file__).resolve().parent.parent / "config"


def _text(realistic: bool) -> str:
    data = yaml.safe_load((CONFIG / "paper000_b_ismc_h50_newton.yaml").read_text())
    data["/**"]["ros__parameters"]["duration"] = 0.3
    if realistic:
        for node, body in data.items():
            if node.endswith("/plant"):
                body["ros__parameters"].update(REALISTIC)
    return yaml.safe_dump(data)


def _loops(text: str) -> list:
    grid = {"ccc.kp": [0.5, 1.0, 4.0], "curve.h": [20.0, 50.0, 80.0], "contour_estimator.max_iterations": [3, 200]}
    return [build_loop(e) for _, e in combinations(text, grid)]


def _same(a, b):
    for name, value in vars(a).items():
        assert np.asarray(value).tobytes() == np.asarray(getattr(b, name)).tobytes(), name


@pytest.mark.skipif(not kernels.ENABLED, reason="numba is not installed (the pure path is the only one)")
@pytest.mark.parametrize("realistic", [False, True])
def test_compiled_newton_on_a_parabola_equals_the_pure_path_bit_for_bit(monkeypatch, realistic):
    text = _text(realistic)
    compiled_batch, compiled = simulate_batch(_loops(text)), [simulate(loop) for loop in _loops(text)[:4]]
    monkeypatch.setattr(kernels, "ENABLED", False)
    pure_batch, pure = simulate_batch(_loops(text)), [simulate(loop) for loop in _loops(text)[:4]]
    for a, b in zip(compiled_batch + compiled, pure_batch + pure, strict=True):
        _same(a, b)


def test_without_numba_the_kernels_answer_none(monkeypatch):
    monkeypatch.setattr(kernels, "numba", None)
    assert kernels.newton_parabola(50.0, -0.02, 0.02, 0.0, 0.0, 0.0, 0.0, 0.9, 0.1, 0.5, 1e-18, 200) is None
    assert kernels.newton_parabola_batch(50.0, -0.02, 0.02, np.zeros((2, 2)), 0.0, 0.0, 0.9, 0.1, 0.5, 1e-18, 200,
                                         np.ones((2, 1), dtype=bool)) is None
