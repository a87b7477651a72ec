"""The compiled kernels (contouring_ros/core/kernels.py, numba where installed) give the pure path's runs bit for bit."""
from pathlib import Path

import numpy as np
import pytest
import yaml

from contouring_ros.config import build_loop
from contouring_ros.core import curves, kernels
from contouring_ros.core.batch import stack as batch_stack
from contouring_ros.core.batch import simulate_batch
from contouring_ros.core.estimators import NewtonEstimator
from contouring_ros.core.simulation import simulate
from contouring_ros.sweep import combinations
from contouring_ros.tuning import REALISTIC

CONFIG = Path(__file__).resolve().parents[2] / "config"


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


compiled_only = pytest.mark.skipif(not kernels.ENABLED, reason="numba is not installed (the pure path is the only one)")

#: every curve with a formula, open and closed, planar and in space
CURVES = [curves.Parabola(0.02, 50.0), curves.Circle(0.05, (0.01, -0.02)), curves.Ellipse(0.03, 0.01, (0.03, 0.0)),
          curves.FigureEight(0.03, 0.02, (0.0, 0.01)), curves.Helix(0.02, 0.03, 0.005, 2.0 * np.pi, 1.0),
          curves.Saddle(0.05, 0.04, 0.01), curves.Butterfly(0.01, (0.001, -0.002))]


def _positions(curve, count: int, seed: int = 3):
    """Points scattered 0.3 mm about the whole curve, in order along it."""
    theta = np.linspace(*curve.domain, count)
    return curve.point(theta) + np.random.default_rng(seed).normal(0.0, 3e-4, (count, curve.dimension))


def _flows(curve, positions, batch: int) -> list:
    """(theta, filtered, iterations, capped) after each position: one estimate alone, and a batch of
    ``batch`` estimates with their own k' (a stacked number), each member its own offset of the position."""
    alone = NewtonEstimator(curve, 500.0, 500.0, curve.domain[0], 1e-3)
    members = batch_stack([NewtonEstimator(curve, 500.0 + 20.0 * j, 500.0, curve.domain[0], 1e-3) for j in range(batch)])
    offsets = np.linspace(-1e-4, 1e-4, batch)[:, None]
    out = []
    for p in positions:
        capped = alone._iterate(p)
        out.append((alone.theta, alone.filtered, alone.iterations, capped))
        capped = members._iterate_batch(p + offsets)
        out.append((members.theta.copy(), members.filtered.copy(), np.asarray(members.iterations).copy(), capped))
    return out


@compiled_only
@pytest.mark.parametrize("curve", CURVES, ids=lambda c: type(c).__name__)
def test_the_compiled_flow_is_the_pure_flow_bit_for_bit_on_every_curve_alone_and_batched(monkeypatch, curve):
    positions = _positions(curve, 150)
    compiled = _flows(curve, positions, 5)
    assert kernels.newton_flow(curve) is not None
    monkeypatch.setattr(kernels, "ENABLED", False)
    assert kernels.newton_flow(curve) is None
    pure = _flows(curve, positions, 5)
    assert any(np.any(o[2] > 10) for o in pure)           # the flow iterates: the comparison means something
    for a, b in zip(compiled, pure, strict=True):
        for x, y in zip(a, b, strict=True):
            assert np.asarray(x).tobytes() == np.asarray(y).tobytes()


@compiled_only
@pytest.mark.parametrize("realistic", [False, True])
def test_compiled_newton_on_a_parabola_equals_the_pure_path_bit_for_bit(monkeypatch, realistic):
    text = _text(realistic)
    compiled_batch, compiled = simulate_batch(_loops(text)), [simulate(loop) for loop in _loops(text)[:4]]
    monkeypatch.setattr(kernels, "ENABLED", False)
    pure_batch, pure = simulate_batch(_loops(text)), [simulate(loop) for loop in _loops(text)[:4]]
    for a, b in zip(compiled_batch + compiled, pure_batch + pure, strict=True):
        _same(a, b)


@compiled_only
def test_compiled_newton_on_the_butterfly_equals_the_pure_path_bit_for_bit(monkeypatch):
    """A closed curve of sin, cos and exp through the whole loop (paper 002's scenario, the realistic machine)."""
    data = yaml.safe_load((CONFIG / "paper002_butterfly_c4_foot_point_ccc.yaml").read_text())
    data["/**"]["ros__parameters"]["duration"] = 0.4
    data["/contour_estimator"]["ros__parameters"] = {"type": "newton", "k_prime": 500.0, "c_prime": 500.0}
    for node, body in data.items():
        if node.endswith("/plant"):
            body["ros__parameters"].update(REALISTIC)
    text = yaml.safe_dump(data)

    def runs():
        loops = [build_loop(e) for _, e in combinations(text, {"ccc.kp": [1.0, 3.0]})]
        return [simulate(loop) for loop in loops] + simulate_batch([build_loop(e) for _, e in combinations(
            text, {"ccc.kp": [1.0, 3.0]})])
    compiled = runs()
    monkeypatch.setattr(kernels, "ENABLED", False)
    pure = runs()
    for a, b in zip(compiled, pure, strict=True):
        _same(a, b)


def test_without_numba_or_a_formula_there_is_no_compiled_flow(monkeypatch):
    spline = curves.SplineCurve([[0.0, 0.0], [0.01, 0.005], [0.02, 0.0], [0.03, 0.01]])
    assert spline.formula is None and kernels.newton_flow(spline) is None

    class Wider(curves.Butterfly):           # a plugin's subclass with columns of its own: not the formula's
        def columns(self, u):
            return super().columns(1.1 * u)
    assert kernels.formula_of(Wider(0.01)) is None and kernels.newton_flow(Wider(0.01)) is None
    assert kernels.newton_flow_batch(spline, np.zeros((2, 2)), 0.0, 0.0, 0.9, 0.1, 0.5, 1e-18, 200,
                                     np.ones((2, 1), dtype=bool)) is None
    monkeypatch.setattr(kernels, "ENABLED", False)
    assert kernels.newton_flow(CURVES[0]) is None
    assert kernels.newton_flow_batch(CURVES[0], np.zeros((2, 2)), 0.0, 0.0, 0.9, 0.1, 0.5, 1e-18, 200,
                                     np.ones((2, 1), dtype=bool)) is None


def test_every_formula_is_its_curve_s_columns():
    """The formula the kernel compiles is the curve's own code: columns() is formula(theta, parameters)."""
    for curve in CURVES:
        for theta in (curve.domain[0], 0.3 * curve.domain[1], np.linspace(*curve.domain, 7)):
            assert np.array_equal(curve.derivatives(theta, order=3),
                                  curves._stack(curve.formula(theta, curve.parameters), theta, 3))


def test_the_graph_s_nodes_run_the_pure_path():
    """A node compiles nothing at start (numba's import and compilation take seconds): the runner's node
    environment turns the kernels off unless the user's own environment says otherwise."""
    from contouring_ros.runner import private_environment
    assert private_environment(7)["CONTOURING_ROS_NUMBA"] == "0"
