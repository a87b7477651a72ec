"""Contour error estimators against exact answers."""
import numpy as np
import pytest
from numpy.testing import assert_allclose

from contouring_ros.core.curves import Butterfly, Circle, Ellipse, Helix, Line, Parabola
from contouring_ros.core.batch import stack
from contouring_ros.core.estimators import (FootPointSearchEstimator, LocalApproximationEstimator,
                                            NaturalLocalEstimator, NewtonEstimator, OsculatingCircleEstimator,
                                            TangentLineEstimator, first_order_terms)
from contouring_ros.core.geometry import ExactContourError
from contouring_ros.core.interpolation import Reference, UniformSchedule, reference


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


@pytest.mark.parametrize("tolerance", [1e-9, 1e-13])
@pytest.mark.parametrize("start", [-0.015, 0.0, 0.01])
def test_newton_converges_to_the_exact_foot_point(start, tolerance):
    parabola = Parabola(0.02, 100.0)
    point = np.array([0.004, 0.0025])
    exact = ExactContourError(parabola)(point)
    estimator = NewtonEstimator(parabola, k_prime=500.0, c_prime=500.0, theta0=start, inner_step=0.001,
                                tolerance=tolerance)
    ref = reference(parabola, UniformSchedule(-0.02, 0.02, 2.0), 0.0)
    for _ in range(10):
        estimate = estimator.step(ref, point)
    speed = np.linalg.norm(parabola.derivatives(exact.theta[0], 1)[1])
    assert abs(estimate.theta - exact.theta[0]) * speed <= tolerance      # within the tolerance along the curve
    assert_allclose(np.linalg.norm(estimate.vector), exact.distance[0], rtol=1e-9)
    assert estimator.cap_reached == 0


def test_newton_tracks_exact_error_10x_closer_than_tangent_line_on_deep_parabola():
    # Paper 000's estimation claim (section IV, Fig. 7): on the h = 100 parabola, with tracking errors
    # of about a millimetre, the static tangent-line estimate departs from the exact contour error while
    # the Newton estimate, iterated from the previous step's foot point, stays on it.
    parabola = Parabola(0.02, 100.0)
    schedule = UniformSchedule(-0.02, 0.02, 2.0)
    exact = ExactContourError(parabola)
    newton = NewtonEstimator(parabola, 500.0, 500.0, theta0=-0.02, inner_step=0.001)
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


def _reference_at(curve, theta):
    d = curve.derivatives(theta, order=2)
    return Reference(theta, 1.0, 0.0, d[0], d[1], d[2])


def test_first_order_local_approximation_is_the_tangent_line():
    helix = Helix(0.03, 0.01, 0.1, 2 * np.pi, 4.0)
    rng = np.random.default_rng(5)
    for theta in np.linspace(0.2, 3.8, 9):
        ref = _reference_at(helix, theta)
        point = ref.position + rng.uniform(-1e-3, 1e-3, 3)
        first = LocalApproximationEstimator(helix, first_order_terms).step(ref, point)
        tangent = TangentLineEstimator(helix).step(ref, point)
        assert_allclose(first.vector, tangent.vector, atol=1e-15)
        assert_allclose(first.theta, tangent.theta, atol=1e-14)


@pytest.mark.parametrize("curve,theta", [(Parabola(0.02, 100.0), 0.0), (Helix(0.03, 0.01, 0.1, 2 * np.pi, 4.0), 0.5),
                                         (Helix(0.03, 0.01, 0.1, 2 * np.pi, 4.0), 0.25), (Circle(0.01), 1.0)])
def test_natural_local_beats_the_tangent_line_near_high_curvature(curve, theta):
    """Paper 003 section II-C: with a tangential lag t the tangent line misses kappa t^2 / 2 (eq. 11, 13);
    the natural local cubic (eq. 10, 15-17) leaves an O(t^3) error."""
    exact = ExactContourError(curve)
    ref = _reference_at(curve, theta)
    rng = np.random.default_rng(11)
    worst_tangent = worst_natural = 0.0
    for lag in (2e-4, 5e-4, 1e-3):          # metres behind the reference, along the curve
        for _ in range(5):
            behind = curve.point(theta - lag / np.linalg.norm(curve.derivatives(theta, 1)[1]))
            point = behind + rng.normal(0.0, 2e-5, curve.dimension)
            truth = exact(point).distance[0]
            worst_tangent = max(worst_tangent, abs(np.linalg.norm(TangentLineEstimator(curve).step(ref, point).vector) - truth))
            natural = NaturalLocalEstimator(curve).step(ref, point)
            worst_natural = max(worst_natural, abs(np.linalg.norm(natural.vector) - truth))
    assert worst_natural < 0.2 * worst_tangent
    assert worst_natural < 2e-6


def test_natural_local_is_exact_for_points_on_its_own_cubic():
    """A point on the approximation curve plus an offset along the normal: the estimate is that offset."""
    helix = Helix(0.03, 0.01, 0.1, 2 * np.pi, 4.0)
    ref = _reference_at(helix, 1.3)
    estimator = NaturalLocalEstimator(helix)
    f, _, rotation, kappa, tau, _ = estimator.task_errors(ref, ref.position)
    t, offset = 4e-4, np.array([3e-6, -2e-6])
    local = np.array([t, kappa * t * t / 2 + offset[0], kappa * tau * t**3 / 6 + offset[1]])
    estimate = estimator.step(ref, ref.position + rotation @ local)
    assert_allclose(estimate.vector, -(rotation[:, 1:] @ offset), atol=1e-17)


def test_osculating_circle_is_exact_on_a_circle():
    """Yang & Li's circular approximation (paper 003 eq. 12) is the contour itself on a circle: any point,
    inside or outside, any lag, gives the exact error vector and foot point."""
    circle = Circle(0.06, (0.01, -0.02))
    estimator = OsculatingCircleEstimator(circle)
    exact = ExactContourError(circle)
    rng = np.random.default_rng(2)
    for theta in np.linspace(0.3, 6.0, 12):
        ref = _reference_at(circle, theta)
        on_circle = circle.point(theta - rng.uniform(0.0, 0.3))
        point = circle.center + (on_circle - circle.center) * (1 + rng.uniform(-0.02, 0.02))
        estimate = estimator.step(ref, point)
        truth = exact(point)
        assert_allclose(estimate.vector, truth.vector[0], atol=1e-15)
        assert_allclose(estimate.signed, truth.signed[0], atol=1e-15)
        assert_allclose(circle.wrap(estimate.theta), truth.theta[0], atol=1e-12)


@pytest.mark.parametrize("curve,theta", [(Ellipse(0.03, 0.01), 0.0), (Parabola(0.02, 100.0), 0.0), (Butterfly(0.01), 1.6)])
def test_natural_local_at_least_as_accurate_as_tangent_and_circle_at_curvature_peaks(curve, theta):
    """At a curvature maximum (ellipse and parabola vertices, the butterfly's tightest turn) the natural local
    estimate (paper 003) is at least as close to the exact error as the osculating circle, which is closer
    than the tangent line, for lags up to 1 mm. (Where the curvature changes fast along the curve, the circle
    is up to 20% closer: both use the curvature at the reference point only.)"""
    exact = ExactContourError(curve, window=0.5)
    ref = _reference_at(curve, theta)
    rng = np.random.default_rng(0)
    worst = {"tangent": 0.0, "circle": 0.0, "natural": 0.0}
    estimators = {"tangent": TangentLineEstimator(curve), "circle": OsculatingCircleEstimator(curve),
                  "natural": NaturalLocalEstimator(curve)}
    for lag in (2e-4, 5e-4, 1e-3):
        for _ in range(5):
            point = curve.point(theta - lag / np.linalg.norm(curve.derivatives(theta, 1)[1])) + rng.normal(0, 2e-5, 2)
            truth = exact(point, near=[theta]).distance[0]
            for name, estimator in estimators.items():
                worst[name] = max(worst[name], abs(np.linalg.norm(estimator.step(ref, point).vector) - truth))
    assert worst["natural"] <= worst["circle"] < worst["tangent"]


# --- Newton: iterated to a stated tolerance each step -------------------------------------------------------

def _newton(curve, theta0, **options):
    return NewtonEstimator(curve, k_prime=500.0, c_prime=500.0, theta0=theta0, inner_step=0.001, **options)


@pytest.mark.parametrize("radius", [0.0503, 0.0497, 0.05])      # outside, inside, on the circle
@pytest.mark.parametrize("tolerance", [1e-6, 1e-9, 1e-12])
def test_newton_converges_within_its_tolerance_on_a_circle(radius, tolerance):
    # exact answer: the foot point of P on a circle is along the ray from the centre; the contour error is
    # | |P - c| - r |. One control step from 0.3 rad away (15 mm along the contour).
    circle = Circle(0.05, (0.01, -0.02))
    ref = _reference_at(circle, 0.0)
    for angle in (1.0, -0.4, 3.0):
        point = circle.center + radius * np.array([np.cos(angle), np.sin(angle)])
        estimator = _newton(circle, angle - 0.3, tolerance=tolerance, max_iterations=500)
        estimate = estimator.step(ref, point)
        assert estimator.cap_reached == 0 and 0 < estimator.iterations < 500
        along = abs((circle.wrap(estimate.theta) - circle.wrap(angle) + np.pi) % (2 * np.pi) - np.pi) * 0.05
        assert along <= 1.01 * tolerance      # the foot point, along the contour (to first order, |E^T U|)
        assert abs(np.linalg.norm(estimate.vector) - abs(radius - 0.05)) <= tolerance
        tangent = circle.derivatives(estimate.theta, 1)[1]
        assert abs(estimate.vector @ tangent) / np.linalg.norm(tangent) <= tolerance    # |E^T U|, eq. 14


@pytest.mark.parametrize("line", [Line([0.01, 0.02], [0.31, 0.42]), Line([0.0, 0.01, -0.02], [0.2, -0.1, 0.3])],
                         ids=["planar", "3-D"])
@pytest.mark.parametrize("tolerance", [1e-6, 1e-9])
def test_newton_converges_within_its_tolerance_on_a_line(line, tolerance):
    # exact answer: the orthogonal projection on the line
    rng = np.random.default_rng(7)
    estimator = _newton(line, 0.0, tolerance=tolerance)
    for s in (0.05, 0.12, 0.3, 0.31):
        offset = rng.normal(0.0, 1e-3, line.dimension)
        offset -= (offset @ line.direction) * line.direction
        point = line.start + s * line.direction + offset
        estimate = estimator.step(_reference_at(line, s), point)
        assert estimator.cap_reached == 0
        assert abs(estimate.theta - s) <= tolerance
        assert abs(np.linalg.norm(estimate.vector) - np.linalg.norm(offset)) <= tolerance


def test_newton_stops_at_the_end_of_an_open_contour():
    # P before the start of the line: the start is the foot point, reached without hitting the cap
    line = Line([0.0, 0.0], [0.3, 0.4])
    estimator = _newton(line, 0.05, max_iterations=200)
    point = np.array([-0.006, -0.008]) + np.array([0.4, -0.3]) * 1e-3
    estimate = estimator.step(_reference_at(line, 0.0), point)
    assert estimate.theta == 0.0 and estimator.cap_reached == 0
    assert_allclose(np.linalg.norm(estimate.vector), np.linalg.norm(point), rtol=1e-12)


def _moving_point_on_parabola(n_steps=2001):
    """Paper 000's deep parabola (h = 100) with the axes ~0.7 mm behind the reference and a 20 um normal
    error: (references, points, exact contour error)."""
    parabola = Parabola(0.02, 100.0)
    schedule = UniformSchedule(-0.02, 0.02, 2.0)
    times = np.arange(n_steps) * 0.001
    refs = [reference(parabola, schedule, t) for t in times]
    theta_actual = np.array([r.theta for r in refs]) - 0.0007 * np.clip(times / 0.2, 0, 1)
    d = parabola.derivatives(theta_actual, 1)
    normal = np.stack([-d[1][:, 1], d[1][:, 0]], axis=1) / np.linalg.norm(d[1], axis=1)[:, None]
    points = d[0] + (20e-6 * np.sin(2 * np.pi * times))[:, None] * normal
    return parabola, refs, points, ExactContourError(parabola)(points)


def test_newton_stopping_rule_removes_the_bias_of_a_fixed_count():
    # The old rule, a fixed 20 inner iterations a step, leaves the estimate behind the moving foot point:
    # its error is far above 1e-9 m. Iterated to the tolerance, every step's estimate is within it, and
    # the step takes fewer iterations than the cap (the tolerance, not the cap, stops it).
    parabola, refs, points, exact = _moving_point_on_parabola()
    deviation = {}
    for name, options in {"fixed 20": dict(tolerance=1e-300, max_iterations=20),
                          "converged": dict(tolerance=1e-9, max_iterations=200)}.items():
        estimator = _newton(parabola, -0.02, **options)
        estimates, counts = [], []
        for r, p in zip(refs, points):
            estimates.append(estimator.step(r, p))
            counts.append(estimator.iterations)
        speed = np.linalg.norm(parabola.derivatives(exact.theta, 1)[1], axis=1)
        along = np.abs([e.theta for e in estimates] - exact.theta) * speed
        deviation[name] = np.abs(np.linalg.norm([e.vector for e in estimates], axis=1) - exact.distance)
        if name == "fixed 20":
            # every step but the first (P = R(theta0) exactly, g = 0) misses 1e-300 m
            assert estimator.cap_reached == len(refs) - 1
            assert along.max() > 1e-7 and deviation[name].max() > 1e-8
        else:
            assert estimator.cap_reached == 0
            # |E^T U| <= 1e-9 m at every estimate; the offset along the curve, to first order the same
            residual = [abs(e.vector @ t) / np.linalg.norm(t) for e, t in
                        zip(estimates, parabola.derivatives(np.array([e.theta for e in estimates]), 1)[1])]
            assert max(residual) <= 1e-9 and along.max() <= 1.01e-9 and deviation[name].max() <= 1e-9
            assert max(counts) < 100
    assert deviation["fixed 20"].max() > 100 * deviation["converged"].max()


def test_a_looser_tolerance_stops_sooner():
    parabola, refs, points, exact = _moving_point_on_parabola(600)
    mean_iterations = []
    for tolerance in (1e-6, 1e-9, 1e-12):
        estimator = _newton(parabola, -0.02, tolerance=tolerance, max_iterations=500)
        counts = []
        for r, p in zip(refs, points):
            estimate = estimator.step(r, p)
            counts.append(estimator.iterations)
        assert estimator.cap_reached == 0
        assert abs(np.linalg.norm(estimate.vector) - exact.distance[-1]) <= tolerance
        mean_iterations.append(np.mean(counts))
    assert mean_iterations[0] < mean_iterations[1] < mean_iterations[2]


def test_a_tiny_cap_is_counted():
    parabola, refs, points, _ = _moving_point_on_parabola(50)
    estimator = _newton(parabola, -0.02, max_iterations=3)
    for r, p in zip(refs[1:], points[1:]):
        estimator.step(r, p)
        assert estimator.iterations == 3
    assert estimator.cap_reached == 49
    # a converged step is not counted: a still point, once reached
    circle = Circle(0.05)
    estimator = _newton(circle, 0.9, max_iterations=3)
    point = np.array([0.06 * np.cos(1.0), 0.06 * np.sin(1.0)])
    counts = [estimator.step(_reference_at(circle, 1.0), point) and estimator.cap_reached for _ in range(40)]
    assert counts[0] == 1 and counts[-1] == counts[-2] < 40


def test_foot_point_search_counts_the_steps_at_its_cap():
    circle = Circle(0.05)
    point = np.array([0.051 * np.cos(1.0), 0.051 * np.sin(1.0)])
    ref = _reference_at(circle, 0.2)
    capped = FootPointSearchEstimator(circle, max_iterations=1, tolerance=1e-12)
    capped.step(ref, point)
    assert capped.iterations == 1 and capped.cap_reached == 1
    converging = FootPointSearchEstimator(circle, max_iterations=50, tolerance=1e-12)
    estimate = converging.step(ref, point)
    assert converging.cap_reached == 0 and converging.iterations < 50
    assert abs(np.linalg.norm(estimate.vector) - 0.001) <= 1e-12
    # at the end of an open contour the search stops without counting
    line = Line([0.0, 0.0], [0.3, 0.4])
    at_end = FootPointSearchEstimator(line, max_iterations=5, tolerance=1e-12)
    estimate = at_end.step(_reference_at(line, 0.0), np.array([-0.006, -0.008]))
    assert estimate.theta == 0.0 and at_end.cap_reached == 0 and at_end.iterations == 0


def test_newton_batch_iterates_each_member_to_its_own_convergence():
    # members with different tolerances and caps converge after different counts; each must equal its run
    # alone (same iterates, same count), converged members unchanged while the rest go on
    parabola, refs, points, _ = _moving_point_on_parabola(300)
    options = [dict(tolerance=1e-6), dict(tolerance=1e-9), dict(tolerance=1e-12), dict(max_iterations=4)]
    offsets = np.array([0.0, 2e-5, -3e-5, 1e-4])
    alone = [_newton(parabola, -0.02, **o) for o in options]
    batch = stack([_newton(parabola, -0.02, **o) for o in options])
    for r, p in zip(refs, points):
        positions = p + offsets[:, None] * np.array([0.6, 0.8])
        together = batch.step_batch(r, positions)      # the Newton estimate does not use the reference
        for i, estimator in enumerate(alone):
            estimate = estimator.step(r, positions[i])
            assert_allclose(together.theta[i, 0], estimate.theta, rtol=0, atol=1e-15)
            assert_allclose(together.vector[i], estimate.vector, rtol=0, atol=1e-15)
            assert batch.iterations[i, 0] == estimator.iterations
    assert len(set(batch.iterations[:, 0])) > 1
    assert batch.cap_reached[:, 0].tolist() == [e.cap_reached for e in alone] == [0, 0, 0, len(refs) - 1]


def test_contour_estimator_node_reports_the_cap_count():
    from contouring_ros.nodes.contour_estimator import ContourEstimatorNode
    node = ContourEstimatorNode.__new__(ContourEstimatorNode)       # counters() only: no ROS graph needed
    node.estimator = _newton(Circle(0.05), 0.0, max_iterations=2)
    node.estimator.step(_reference_at(Circle(0.05), 1.0), np.array([0.0, 0.051]))
    assert node.counters() == {"branch recoveries": 0, "iteration cap reached": 1}
    node.estimator = FootPointSearchEstimator(Circle(0.05), max_iterations=1, tolerance=1e-12)
    node.estimator.step(_reference_at(Circle(0.05), 1.0), np.array([0.0, 0.051]))
    assert node.counters() == {"branch recoveries": 0, "iteration cap reached": 1}
    node.estimator = TangentLineEstimator(Circle(0.05))
    assert node.counters() == {"branch recoveries": 0, "iteration cap reached": 0}
