"""Paper 002's pieces against known answers: the feedrate profile, the foot-point search, the windowed exact
contour error of a self-crossing curve; and the TVT CCC's ordering on the butterfly."""
import numpy as np
import pytest
from numpy.testing import assert_allclose

from contouring_ros.config import build_loop, load_experiment
from contouring_ros.core.curves import Butterfly, Circle, Line, Parabola
from contouring_ros.core.estimators import FootPointSearchEstimator
from contouring_ros.core.geometry import ExactContourError
from contouring_ros.core.interpolation import FeedrateSchedule, Reference, reference
from contouring_ros.core.simulation import simulate
from contouring_ros.records.scoring import score_run
from conftest import CONFIG


def test_feedrate_profile_on_a_line_is_the_trapezoid():
    """Rest to rest over L at feedrate F and acceleration A (L > F^2 / A): duration L / F + F / A."""
    length, feedrate, acceleration = 0.2, 0.1, 0.5
    line = Line([0.0, 0.0], [0.12, 0.16])
    schedule = FeedrateSchedule(line, 0.0, length, feedrate, acceleration)
    assert_allclose(schedule.duration, length / feedrate + feedrate / acceleration, rtol=1e-9)
    t = np.arange(0.0, schedule.duration, 1e-3)
    speed = np.linalg.norm(reference(line, schedule, t).velocity, axis=1)
    expected = np.minimum.reduce([acceleration * t, np.full_like(t, feedrate), acceleration * (schedule.duration - t)])
    assert_allclose(speed, expected, atol=1e-9)


def test_one_steps_feedrate_schedule_on_floats_gives_the_array_paths_numbers_bit_for_bit():
    """FeedrateSchedule._at (a float time, one simulation step) repeats __call__'s array operations on
    Python floats: the same numbers, before, inside and after the profile, at its table's knots too."""
    schedule = FeedrateSchedule(Butterfly(0.01), 0.0, 2 * np.pi, 0.1, 1.0, 5.0)
    times = np.concatenate([np.linspace(-0.01, schedule.duration + 0.01, 3001), schedule._t[:40],
                            [schedule.duration]])
    for t in times:
        scalar = schedule(float(t))
        array = schedule(np.float64(t))          # not a Python float: the array path
        assert scalar == array, (t, scalar, array)


def test_feedrate_profile_respects_the_centripetal_bound_on_a_circle():
    radius, normal_acceleration = 0.01, 0.5
    circle = Circle(radius)
    schedule = FeedrateSchedule(circle, 0.0, 2 * np.pi, 0.2, 2.0, normal_acceleration)
    t = np.arange(0.0, schedule.duration, 1e-3)
    ref = reference(circle, schedule, t)
    speed = np.linalg.norm(ref.velocity, axis=1)
    assert speed.max() == pytest.approx(np.sqrt(normal_acceleration * radius), rel=1e-6)
    # positions and velocities agree: the mean velocity over a sample is the average of its ends, up to
    # |jump in acceleration| Ts / 8 where the profile switches from cruise to braking inside a sample
    assert_allclose(np.diff(ref.position, axis=0) / 1e-3, 0.5 * (ref.velocity[1:] + ref.velocity[:-1]),
                    atol=1.2 * 2.0 * 1e-3 / 8)


@pytest.mark.parametrize("curve,theta", [(Parabola(0.02, 100.0), 0.004), (Butterfly(0.01), 1.6)])
def test_foot_point_search_ends_within_its_tolerance_at_the_exact_foot_point(curve, theta):
    point = curve.point(theta) + np.array([3e-4, -2e-4])
    estimator = FootPointSearchEstimator(curve, max_iterations=50, tolerance=1e-9)
    d = curve.derivatives(theta - 0.002, order=2)
    estimate = estimator.step(Reference(theta - 0.002, 1.0, 0.0, d[0], d[1], d[2]), point)
    foot = curve.derivatives(estimate.theta, order=1)
    assert abs((point - foot[0]) @ foot[1]) / np.linalg.norm(foot[1]) < 1e-9
    exact = ExactContourError(curve, window=0.3)(point, near=[theta])
    assert_allclose(np.linalg.norm(estimate.vector), exact.distance[0], rtol=1e-6)


def test_windowed_exact_contour_error_keeps_a_point_on_its_own_branch():
    """Where the butterfly crosses itself the nearest point of the whole curve can lie on the other
    branch; restricted to +-0.3 rad around the point's own parameter, the error is to its own branch."""
    butterfly = Butterfly(0.01)
    grid = np.linspace(0.0, 2 * np.pi, 200001)
    points = butterfly.point(grid)
    shifted = points[::1000] + 5e-5
    windowed = ExactContourError(butterfly, window=0.3)(shifted, near=grid[::1000])
    assert np.all(np.abs(np.angle(np.exp(1j * (windowed.theta - grid[::1000])))) < 0.3)
    global_ = ExactContourError(butterfly)(shifted)
    assert np.all(windowed.distance >= global_.distance - 1e-15)


def _paper002(method: str):
    loop = build_loop(load_experiment(CONFIG / f"paper002_butterfly_{method}.yaml"))
    return score_run(loop.curve, simulate(loop))


def test_paper002_tvt_below_osculating_below_tangent_line_in_max_contour_error():
    tangent, osculating, tvt = (_paper002(m) for m in ("c1_tangent_line", "c2_osculating_circle", "c3_tvt"))
    assert tvt.mce < osculating.mce < tangent.mce
    assert tvt.estimation_max < 1e-6


CIRCLE_LAP = """\
/**:
  ros__parameters:
    sample_time: 0.001
    axes: ["x", "y"]
    curve: {type: circle, radius: 0.005}
    schedule: {type: feedrate, theta_start: 0.0, theta_end: 6.283185307179586, feedrate: 0.05, acceleration: 1.0,
               normal_acceleration: 0.5}
    settle_time: SETTLE
/x/plant:
  ros__parameters: {model: first_order_velocity, gain: 1.0, time_constant: 0.005}
/y/plant:
  ros__parameters: {model: first_order_velocity, gain: 1.0, time_constant: 0.005}
/x/servo:
  ros__parameters: {law: direct}
/y/servo:
  ros__parameters: {law: direct}
/contour_estimator:
  ros__parameters: {type: foot_point_search, max_iterations: 10, tolerance: 1.0e-6}
/ccc:
  ros__parameters: {type: tvt, kc: 140.0, min_feedrate: 0.001}
"""


def test_settle_time_runs_past_the_schedule():
    from contouring_ros.config import parse_experiment
    plain = parse_experiment(CIRCLE_LAP.replace("SETTLE", "0.0"), "lap")
    settled = parse_experiment(CIRCLE_LAP.replace("SETTLE", "0.4"), "lap")
    assert settled.duration == pytest.approx(plain.duration + 0.4, abs=1e-12)
    assert settled.n_steps == plain.n_steps + 400


def test_tvt_stops_at_the_end_of_a_closed_path():
    """The foot point's parameter wraps from 2 pi to 0 on a closed curve; the TVT follows it unwrapped, so past
    the end the commanded feedrate is 0 and the axes stay at the end point (they used to start a second lap,
    at the profile's start feedrate)."""
    from contouring_ros.config import parse_experiment
    loop = build_loop(parse_experiment(CIRCLE_LAP.replace("SETTLE", "0.5"), "lap"))
    run = simulate(loop)
    end = loop.curve.point(2 * np.pi)
    assert np.linalg.norm(run.position[-1] - end) < 1e-4          # at the end point, +- a small overshoot
    assert np.linalg.norm(run.velocity[-1]) < 1e-6                 # and at rest
    assert loop.controller.theta == pytest.approx(2 * np.pi, abs=0.02)
    travelled = np.sum(np.linalg.norm(np.diff(run.position, axis=0), axis=1))
    assert travelled == pytest.approx(2 * np.pi * 0.005, rel=0.01)  # one lap, not more
