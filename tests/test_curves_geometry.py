"""Curves and the exact contour error against cases with known answers."""
import numpy as np
import pytest
from numpy.testing import assert_allclose

from contouring_ros.core.curves import Circle, Line, Parabola
from contouring_ros.core.geometry import ExactContourError, curvature


@pytest.mark.parametrize("curve", [Parabola(0.02, 50.0), Circle(0.1, (0.01, -0.02)), Line([0, 0, 0], [0.3, 0.1, -0.2])])
def test_derivatives_match_finite_differences(curve):
    lo, hi = curve.domain
    theta = np.linspace(lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo), 7)
    step = 1e-6 * (hi - lo)
    d = curve.derivatives(theta, order=3)
    for order in (1, 2, 3):
        numeric = (curve.derivatives(theta + step, order)[order - 1] - curve.derivatives(theta - step, order)[order - 1]) / (2 * step)
        assert_allclose(d[order], numeric, rtol=1e-5, atol=1e-6 * np.max(np.abs(d[order - 1])) + 1e-9)


def test_circle_exact_error_is_radial_distance():
    # Reference: the distance from P to a circle of radius r about c is | |P - c| - r |.
    circle = Circle(0.1, (0.02, 0.03))
    rng = np.random.default_rng(1)
    angles = rng.uniform(0, 2 * np.pi, 200)
    radii = 0.1 + rng.uniform(-0.02, 0.02, 200)
    points = np.array([0.02, 0.03]) + radii[:, None] * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    foot = ExactContourError(circle)(points)
    assert_allclose(foot.distance, np.abs(radii - 0.1), atol=1e-15)
    # Inside the circle the axes lie left of the counter-clockwise contour: the error points outwards.
    assert np.all(np.sign(foot.signed[radii < 0.1]) == -1)


def test_parabola_exact_error_agrees_with_brute_force_and_residual():
    parabola = Parabola(0.02, 100.0)
    rng = np.random.default_rng(2)
    theta = rng.uniform(-0.018, 0.018, 100)
    d = parabola.derivatives(theta, 1)
    normal = np.stack([-d[1][:, 1], d[1][:, 0]], axis=1) / np.linalg.norm(d[1], axis=1)[:, None]
    points = d[0] + rng.uniform(-1e-3, 1e-3, 100)[:, None] * normal
    foot = ExactContourError(parabola)(points)
    dense = parabola.point(np.linspace(-0.02, 0.02, 400001))
    brute = np.array([np.min(np.linalg.norm(dense - p, axis=1)) for p in points])
    assert_allclose(foot.distance, brute, atol=1e-9)
    # residual: at the foot point the error vector is normal to the curve (gradient of J is zero)
    tangent = parabola.derivatives(foot.theta, 1)[1]
    assert_allclose(np.sum(foot.vector * tangent, axis=1), 0.0, atol=1e-17)


def test_points_on_the_curve_have_zero_error():
    parabola = Parabola(0.02, 50.0)
    points = parabola.point(np.linspace(-0.02, 0.02, 101))
    assert_allclose(ExactContourError(parabola)(points).distance, 0.0, atol=1e-15)


def test_curvature_of_circle_and_parabola_vertex():
    assert_allclose(curvature(Circle(0.25), np.linspace(0, 6, 5)), 4.0)
    assert_allclose(curvature(Parabola(0.02, 50.0), 0.0), 100.0)
