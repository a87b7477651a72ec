"""Contour error estimators against exact answers."""
import numpy as np
import pytest
from numpy.testing import assert_allclose

from contouring_ros.core.curves import Line, Parabola
from contouring_ros.core.estimators import NewtonEstimator, TangentLineEstimator
from contouring_ros.core.geometry import ExactContourError
from contouring_ros.core.interpolation import UniformSchedule, reference


def test_tangent_line_is_exact_on_a_line():
    line = Line([0.0, 0.0], [0.3, 0.4])
    schedule = UniformSchedule(0.0, 0.5, 1.0)
    estimator = TangentLineEstimator(line)
    rng = np.random.default_rng(3)
    for t in np.linspace(0.1, 0.9, 20):
        ref = reference(line, schedule, t)
        point = ref.position + rng.uniform(-2e-3, 2e-3, 2)
        estimate = estimator.step(ref, point)
        exact = ExactContourError(line)(point)
        assert_allclose(estimate.vector, exact.vector[0], atol=1e-15)
        assert_allclose(estimate.signed, exact.signed[0], atol=1e-15)
        assert_allclose(estimate.theta, exact.theta[0], atol=1e-14)


@pytest.mark.parametrize("start", [-0.015, 0.0, 0.01])
def test_newton_converges_to_the_exact_foot_point(start):
    parabola = Parabola(0.02, 100.0)
    point = np.array([0.004, 0.0025])
    exact = ExactContourError(parabola)(point)
    estimator = NewtonEstimator(parabola, k_prime=500.0, c_prime=500.0, theta0=start, iterations=20,
                                inner_step=0.001)
    ref = reference(parabola, UniformSchedule(-0.02, 0.02, 2.0), 0.0)
    for _ in range(10):
        estimate = estimator.step(ref, point)
    assert_allclose(estimate.theta, exact.theta[0], atol=1e-12)
    assert_allclose(np.linalg.norm(estimate.vector), exact.distance[0], rtol=1e-9)


def test_newton_tracks_exact_error_10x_closer_than_tangent_line_on_deep_parabola():
    # Paper 000's estimation claim (section IV, Fig. 7): on the h = 100 parabola, with tracking errors
    # of about a millimetre, the static tangent-line estimate departs from the exact contour error while
    # the Newton estimate, iterated from the previous step's foot point, stays on it.
    parabola = Parabola(0.02, 100.0)
    schedule = UniformSchedule(-0.02, 0.02, 2.0)
    exact = ExactContourError(parabola)
    newton = NewtonEstimator(parabola, 500.0, 500.0, theta0=-0.02, iterations=20, inner_step=0.001)
    tangent = TangentLineEstimator(parabola)
    times = np.arange(0, 2001) * 0.001
    lag = 0.0007 * np.clip(times / 0.2, 0, 1)              # the axes fall ~0.7 mm behind along theta
    refs = [reference(parabola, schedule, t) for t in times]
    theta_actual = np.array([r.theta for r in refs]) - lag
    d = parabola.derivatives(theta_actual, 1)
    normal = np.stack([-d[1][:, 1], d[1][:, 0]], axis=1) / np.linalg.norm(d[1], axis=1)[:, None]
    points = d[0] + (20e-6 * np.sin(2 * np.pi * times))[:, None] * normal
    tracking = np.linalg.norm(np.array([r.position for r in refs]) - points, axis=1)
    assert tracking.max() > 1e-3                            # tracking errors reach a millimetre
    truth = exact(points).distance
    newton_dev = np.abs([np.linalg.norm(newton.step(r, p).vector) for r, p in zip(refs, points)] - truth)
    tangent_dev = np.abs([np.linalg.norm(tangent.step(r, p).vector) for r, p in zip(refs, points)] - truth)
    assert tangent_dev.max() > 10 * newton_dev.max()
    assert newton_dev.max() < 1e-6
