"""The compiled kernels (contouring_ros/core/kernels.py, numba where installed) give the pure path's runs bit for bit."""
import warnings
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
from contouring_ros.studies.sweep import combinations
from contouring_ros.studies.machine import REALISTIC

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


@pytest.fixture(autouse=True)
def compile_at_once(monkeypatch):
    """The kernels compile at the first step (a process compiles after COMPILE_AFTER pure steps)."""
    monkeypatch.setattr(kernels, "COMPILE_AFTER", 0)


def test_a_process_compiles_only_after_its_pure_steps(monkeypatch):
    """A short run alone never waits for numba: the flow runs pure for COMPILE_AFTER steps of the process."""
    monkeypatch.setattr(kernels, "COMPILE_AFTER", 3)
    monkeypatch.setattr(kernels, "_pure_steps", 0)
    monkeypatch.setattr(kernels, "ENABLED", True)
    monkeypatch.setattr(kernels, "_flow_for", lambda curve: "compiled")
    monkeypatch.setattr(kernels, "_FLOWS", __import__("weakref").WeakKeyDictionary())
    assert [kernels.newton_flow(CURVES[0]) for _ in range(5)] == [None, None, None, "compiled", "compiled"]

#: every curve with a formula, open and closed, planar and in space
CURVES = [curves.Parabola(0.02, 50.0), curves.Circle(0.05, (0.01, -0.02)), curves.Ellipse(0.03, 0.01, (0.03, 0.0)),
          curves.FigureEight(0.03, 0.02, (0.0, 0.01)), curves.Helix(0.02, 0.03, 0.005, 2.0 * np.pi, 1.0),
          curves.Saddle(0.05, 0.04, 0.01), curves.Butterfly(0.01, (0.001, -0.002))]


def _positions(curve, count: int, seed: int = 3):
    """Points scattered 0.3 mm about the whole curve, in order along it."""
    theta = np.linspace(*curve.domain, count)
    return curve.point(theta) + np.random.default_rng(seed).normal(0.0, 3e-4, (count, curve.dimension))


def _members(curve, count: int) -> list:
    """``count`` curves like ``curve``, each with its first parameter a little larger: a batch's stacked
    curve then has parameters (and for some, a domain) of its own per member."""
    if isinstance(curve, curves.Parabola):
        return [curves.Parabola(curve.a, curve.h * (1.0 + 0.05 * j)) for j in range(count)]
    if isinstance(curve, curves.Butterfly):
        return [curves.Butterfly(curve.scale * (1.0 + 0.05 * j), curve.center) for j in range(count)]
    if isinstance(curve, curves.Circle):
        return [curves.Circle(curve.radius * (1.0 + 0.05 * j), curve.center) for j in range(count)]
    if isinstance(curve, (curves.Ellipse, curves.FigureEight)):
        return [type(curve)(curve.a * (1.0 + 0.05 * j), curve.b, curve.center) for j in range(count)]
    if isinstance(curve, curves.Helix):
        return [curves.Helix(curve.a * (1.0 + 0.05 * j), curve.b, curve.c, curve.omega, curve.domain[1])
                for j in range(count)]
    return [curves.Saddle(curve.a, curve.b, curve.h, curve.omega * (1.0 + 0.05 * j)) for j in range(count)]


def _flows(curve, positions, batch: int) -> list:
    """(theta, filtered, iterations, capped) after each position: one estimate alone, and a batch of
    ``batch`` estimates, each with its own k' and its own curve (stacked numbers), each member its own
    offset of the position."""
    alone = NewtonEstimator(curve, 500.0, 500.0, curve.domain[0], 1e-3)
    members = batch_stack([NewtonEstimator(c, 500.0 + 20.0 * j, 500.0, curve.domain[0], 1e-3)
                           for j, c in enumerate(_members(curve, batch))])
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
    stacked = batch_stack(_members(curve, 5))
    assert any(isinstance(v, np.ndarray) for v in stacked.parameters)      # the members' curves differ
    # the compiled paths run (neither falls back to the pure one)
    assert kernels.newton_flow(curve) is not None
    assert kernels.newton_flow_batch(stacked, np.zeros((5, curve.dimension)), curve.domain[0], 0.0, 0.9, 0.1, 0.5,
                                     1e-18, 200, np.ones((5, 1), dtype=bool)) is not None
    compiled = _flows(curve, positions, 5)
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


@compiled_only
def test_every_compiled_formula_is_its_curve_s_columns_bit_for_bit():
    """The formula numba compiles (the math module's sin, cos, exp) gives the point and tangent the curve's
    columns() give, to the last bit, on every curve, at its ends and inside, on and off its domain."""
    for curve in CURVES:
        formula = kernels.compiled_formula(curve.formula)
        lo, hi = curve.domain
        for theta in np.concatenate([[lo, hi, -0.0, 0.0], np.linspace(lo - 1.0, hi + 1.0, 400)]).tolist():
            point, tangent = formula(theta, curve.parameters)[:2]
            assert (point, tangent) == tuple(curve.columns(theta)[:2]), (type(curve).__name__, theta)


def test_a_broken_numba_leaves_the_pure_path_with_a_warning(monkeypatch):
    """numba installed but failing to import (built for another numpy, say): the estimate runs its pure path,
    with the same numbers, and says so once."""
    monkeypatch.setattr(kernels, "ENABLED", True)
    monkeypatch.setattr(kernels, "_KERNELS", {})
    monkeypatch.setattr(kernels, "_FLOWS", __import__("weakref").WeakKeyDictionary())
    monkeypatch.setattr(kernels, "_numba", lambda: kernels._unavailable("numba cannot be imported (test)"))
    curve = CURVES[-1]
    with pytest.warns(RuntimeWarning, match="pure Python path"):
        assert kernels.newton_flow(curve) is None
    estimate = NewtonEstimator(curve, 500.0, 500.0, 0.0, 1e-3)
    estimate._iterate(_positions(curve, 3)[1])
    assert estimate.iterations > 10


def test_a_zero_tangent_raises_as_the_pure_path_does(monkeypatch):
    """A degenerate curve (|R'| = 0 in floats) raises ZeroDivisionError with numba or without: the kernel's
    first call finds it (its flow divides as Python's floats do) and leaves the curve to the pure path."""
    curve, compiled = curves.Circle(1e-170), kernels.ENABLED
    for enabled in (compiled, False):
        monkeypatch.setattr(kernels, "ENABLED", enabled)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            with pytest.raises(ZeroDivisionError):
                NewtonEstimator(curve, 500.0, 500.0, 0.0, 1e-3)._iterate(np.array([0.001, 0.0]))
    if compiled:
        flow = kernels._kernels(curve.formula, False)[0]
        with pytest.raises(ZeroDivisionError):
            flow(curve.parameters, np.array([0.001, 0.0]), 0.0, 0.0, 0.5, 0.5, 0.5, 1e-18, 10, 0.0, 2 * np.pi, True)


def test_the_graph_s_nodes_run_the_pure_path():
    """A node compiles nothing at start (numba's import and compilation take seconds): the runner's node
    environment turns the kernels off unless the user's own environment says otherwise."""
    from contouring_ros.run.runner import private_environment
    assert private_environment(7)["CONTOURING_ROS_NUMBA"] == "0"
