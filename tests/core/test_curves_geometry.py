"""Curves and the exact contour error against cases with known answers."""
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from contouring_ros.core.curves import (Butterfly, Circle, Curve, Ellipse, FigureEight, Helix, Line, Parabola, Saddle,
                                       SplineCurve, ToolPath)
from contouring_ros.core.gcode import parse_program
from contouring_ros.core.geometry import ExactContourError, curvature, frenet_frame


@pytest.mark.parametrize("curve", [Parabola(0.02, 50.0), Circle(0.1, (0.01, -0.02)), Line([0, 0, 0], [0.3, 0.1, -0.2]),
                                   Ellipse(0.03, 0.01, (0.03, 0.0)), FigureEight(0.03, 0.03),
                                   Helix(0.03, 0.01, 0.1, 2 * np.pi, 4.0), Saddle(0.002, 0.003, 0.0005), Butterfly(0.01),
                                   SplineCurve([[0, 0, 0], [0.01, 0.01, 0.002], [0.02, 0, 0.004], [0.03, -0.01, 0.003],
                                                [0.04, 0, 0.0]]),
                                   ToolPath([0.0, 0.0], ["G3 X0.06 Y0 I0.03 J0"])])
def test_derivatives_match_finite_differences(curve):
    lo, hi = curve.domain
    theta = np.linspace(lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo), 7)
    step = 1e-6 * (hi - lo)
    d = curve.derivatives(theta, order=3)
    for order in (1, 2, 3):
        numeric = (curve.derivatives(theta + step, order)[order - 1] - curve.derivatives(theta - step, order)[order - 1]) / (2 * step)
        assert_allclose(d[order], numeric, rtol=1e-5, atol=1e-6 * np.max(np.abs(d[order - 1])) + 1e-9)


CURVES = [Circle(0.1, (0.01, -0.02)), Ellipse(0.03, 0.01, (0.03, 0.0)), FigureEight(0.03, 0.03),
          Helix(0.03, 0.01, 0.1, 2 * np.pi, 4.0), Saddle(0.002, 0.003, 0.0005), Butterfly(0.01),
          ToolPath([0.0, 0.0], ["G3 X0.06 Y0 I0.03 J0"])]


@pytest.mark.parametrize("curve", CURVES, ids=lambda c: type(c).__name__)
def test_one_steps_scalar_path_gives_the_array_paths_numbers_bit_for_bit(curve):
    """A float parameter takes math's sin, cos and exp (curves._scalar_or_array), an array numpy's: the
    simulation's numbers must not depend on which (a single run and a batch give the same run)."""
    lo, hi = curve.domain
    for theta in np.linspace(lo, hi, 401):
        scalar = curve.derivatives(float(theta), order=3)
        array = curve.derivatives(np.array([theta]), order=3)[:, 0, :]
        np.testing.assert_array_equal(scalar, array)
    with np.errstate(invalid="ignore"):       # math refuses an infinite angle: numpy's nan instead, no error
        assert np.isnan(curve.columns(float("inf"))[0][0])


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


def test_far_points_are_searched_among_coarse_samples_and_keep_their_exact_distance():
    # a point many coarse spacings off the curve (a run that nearly diverged) is searched among every
    # COARSE-th sample; its distance is still the exact one: | |P - c| - r | for a circle, the centre included
    circle = Circle(0.1, (0.02, 0.03))
    solver = ExactContourError(circle)
    rng = np.random.default_rng(3)
    angles = rng.uniform(0, 2 * np.pi, 400)
    radii = np.concatenate([[0.0], rng.uniform(0.0, 0.08, 199), rng.uniform(0.12, 0.4, 200)])
    points = np.array([0.02, 0.03]) + radii[:, None] * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    far = np.abs(radii - 0.1) > solver._far
    assert far.sum() > 300 and (~far).sum() > 10          # most of them far, some not
    assert_allclose(solver(points).distance, np.abs(radii - 0.1), rtol=1e-12, atol=1e-15)
    # on a parabola, far on either side, against a brute-force search of a dense sampling
    parabola = Parabola(0.02, 50.0)
    theta = rng.uniform(-0.018, 0.018, 100)
    d = parabola.derivatives(theta, 1)
    normal = np.stack([-d[1][:, 1], d[1][:, 0]], axis=1) / np.linalg.norm(d[1], axis=1)[:, None]
    points = d[0] + rng.uniform(-0.03, 0.03, 100)[:, None] * normal
    foot = ExactContourError(parabola)(points)
    dense = parabola.point(np.linspace(-0.02, 0.02, 400001))
    brute = np.array([np.min(np.linalg.norm(dense - p, axis=1)) for p in points])
    assert_allclose(foot.distance, brute, rtol=1e-5, atol=1e-9)


def test_points_on_the_curve_have_zero_error():
    parabola = Parabola(0.02, 50.0)
    points = parabola.point(np.linspace(-0.02, 0.02, 101))
    assert_allclose(ExactContourError(parabola)(points).distance, 0.0, atol=1e-15)


def test_curvature_of_circle_and_parabola_vertex():
    assert_allclose(curvature(Circle(0.25), np.linspace(0, 6, 5)), 4.0)
    assert_allclose(curvature(Parabola(0.02, 50.0), 0.0), 100.0)


def test_frenet_frame_of_a_circular_helix_has_the_textbook_curvature_and_torsion():
    """Helix (r cos phi, r sin phi, c phi): kappa = r / (r^2 + c^2), tau = c / (r^2 + c^2) (paper 003 eq. 4-5).
    Helix(a=b=r, c=0.1, omega=2 pi) rises 0.1 per turn: c = 0.1 / (2 pi) per radian."""
    r, c = 0.03, 0.1 / (2 * np.pi)
    helix = Helix(r, r, 0.1, 2 * np.pi, 4.0)
    frame = frenet_frame(helix, 0.37, 1.0)
    assert_allclose(frame.curvature, r / (r * r + c * c), rtol=1e-12)
    assert_allclose(frame.torsion, c / (r * r + c * c), rtol=1e-12)
    assert_allclose(frame.rotation.T @ frame.rotation, np.eye(3), atol=1e-14)
    assert_allclose(np.linalg.det(frame.rotation), 1.0, rtol=1e-14)


@pytest.mark.parametrize("curve,theta_dot", [(Helix(0.03, 0.01, 0.1, 2 * np.pi, 4.0), 1.0),
                                             (Ellipse(0.03, 0.01), 1.8 * np.pi), (FigureEight(0.03, 0.03), np.pi)])
def test_frenet_frame_rates_match_finite_differences(curve, theta_dot):
    """dR/dt = -v R G and d2R/dt2 (paper 003, after eq. 19) against differences of R along the motion."""
    theta, step = 1.1, 1e-6
    frames = [frenet_frame(curve, theta + d * step, theta_dot) for d in (-1, 0, 1)]
    rate = (frames[2].rotation - frames[0].rotation) / (2 * step / theta_dot)
    acceleration = (frames[2].rotation_rate - frames[0].rotation_rate) / (2 * step / theta_dot)
    scale = np.abs(frames[1].rotation_acceleration).max()
    assert_allclose(frames[1].rotation_rate, rate, atol=1e-7 * np.abs(rate).max())
    assert_allclose(frames[1].rotation_acceleration, acceleration, atol=1e-5 * scale)


def test_spline_passes_through_its_points_at_their_chord_lengths():
    points = np.array([[0.0, 0.0], [0.01, 0.01], [0.02, 0.0], [0.03, -0.01], [0.04, 0.0]])
    spline = SplineCurve(points)
    chords = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    assert_allclose(spline.point(chords), points, atol=1e-15)
    closed = SplineCurve(points, closed=True)
    assert closed.closed and closed.domain[1] > spline.domain[1]
    assert_allclose(closed.derivatives(closed.domain[1], 2), closed.derivatives(0.0, 2), atol=1e-9)


@pytest.mark.parametrize("path", [
    ToolPath([0.0, 0.0], ["G1 X0.05 Y0", "G3 X0.08 Y0.03 I0 J0.03", "G1 X0.08 Y0.06", "G2 X0.1 Y0.06 I0.01 J0"]),
    ToolPath.from_program(parse_program("G21 G64 P0.01 G1 X10 Y0 F600\nX12 Y3\nG3 X14 Y5 Z2 I2 J0\nG1 X9 Y9 Z0\n"
                                        "X0 Y4\n"), blend_tolerance=0.01)], ids=["inline", "program"])
def test_a_tool_path_s_columns_over_many_segments_are_each_point_s_own(path):
    """An array of parameters across every segment (lines, arcs, a helix, blends; the exact contour error's
    Newton steps ask for all samples at once) gives each point's own numbers bit for bit."""
    theta = np.random.default_rng(3).uniform(*path.domain, 500)
    columns = path.derivatives(theta, order=3)
    assert len({segment[0] for segment in path.segments}) == 2 and len(path.segments) >= 4
    for k, value in enumerate(theta):
        np.testing.assert_array_equal(columns[:, k, :], path.derivatives(float(value), order=3))


def test_tool_path_of_lines_and_arcs():
    """G1 50 mm along x, G3 quarter circle of radius 30 mm, G1 30 mm along y: length 80 mm + 15 pi mm,
    unit speed everywhere, curvature 0 on the lines and 1/30 mm on the arc."""
    path = ToolPath([0.0, 0.0], ["G1 X0.05 Y0", "G3 X0.08 Y0.03 I0 J0.03", "G1 X0.08 Y0.06"])
    assert_allclose(path.domain[1], 0.08 + 0.015 * np.pi, rtol=1e-12)
    s = np.linspace(0.0, path.domain[1], 101)
    assert_allclose(np.linalg.norm(path.derivatives(s, 1)[1], axis=1), 1.0, rtol=1e-12)
    assert_allclose(path.point(path.domain[1]), [0.08, 0.06], atol=1e-15)
    assert_allclose(curvature(path, [0.02, 0.05 + 0.0075 * np.pi, 0.1]), [0.0, 1 / 0.03, 0.0], atol=1e-9)
    clockwise = ToolPath([0.0, 0.0], ["G2 X0.06 Y0 I0.03 J0"])
    assert_allclose(clockwise.point(0.015 * np.pi), [0.03, 0.03], atol=1e-15)


@pytest.mark.parametrize("moves,message", [(["G1 X0 Y0"], "a line of zero length"),
                                           (["G3 X0.05 Y0 I0 J0.03"], "not on the arc's circle"),
                                           (["G2 X0.05 Y0"], "needs its centre offset"),
                                           (["M3 S1000"], "expected G1, G2 or G3"),
                                           (["G1 Xfast"], "expected words like X0.05")])
def test_tool_path_refuses_bad_moves(moves, message):
    with pytest.raises(ValueError, match=message):
        ToolPath([0.0, 0.0], moves)


def test_equal_curves_share_one_exact_solver_and_it_gives_what_a_fresh_one_gives():
    """A tuning scores thousands of runs of one curve, each run with its own curve object: equal curves share
    one solver (its dense samples made once); an unequal curve gets its own; the distances are a fresh
    solver's, with a window around each point's reference parameter too."""
    from contouring_ros.core.metrics import exact_solver
    first, same, other = Parabola(0.02, 0.05), Parabola(0.02, 0.05), Parabola(0.02, 0.1)
    assert exact_solver(first) is exact_solver(same) and exact_solver(other) is not exact_solver(first)
    rng = np.random.default_rng(4)
    points = first.point(np.sort(rng.uniform(*first.domain, 300))) + rng.normal(0.0, 1e-4, (300, 2))
    assert np.array_equal(exact_solver(same)(points).distance, ExactContourError(Parabola(0.02, 0.05))(points).distance)
    loop = Butterfly(0.01)
    loop.contour_error_window = 0.3
    theta = np.sort(rng.uniform(*loop.domain, 200))
    points = loop.point(theta) + rng.normal(0.0, 3e-4, (200, 2))
    fresh = ExactContourError(Butterfly(0.01), window=0.3)(points, near=theta)
    assert np.array_equal(exact_solver(loop)(points, near=theta).distance, fresh.distance)


def test_a_curve_that_refers_back_to_itself_gets_its_own_solver():
    from contouring_ros.core.metrics import exact_solver
    first, second = Parabola(0.02, 0.05), Parabola(0.02, 0.05)
    first.owner, second.owner = first, second         # a plugin's curve may keep a reference to itself
    exact_solver(first)
    assert exact_solver(second).curve is second


class _ThinLoop(Curve):
    """An ellipse 2 m long and 40 um wide whose parametrisation starts off its axis, so that the samples of
    its two long branches do not lie above one another: a point of one branch is often nearer a sample of
    the other than any of its own (spacing 0.3 mm)."""

    dimension, domain, closed = 2, (0.0, 2.0 * np.pi), True
    a, b, shift = 1.0, 2e-5, 0.1234

    def columns(self, t):
        c, s = np.cos(t + self.shift), np.sin(t + self.shift)
        return [(self.a * c, self.b * s), (-self.a * s, self.b * c), (-self.a * c, -self.b * s), (self.a * s, -self.b * c)]


def test_a_point_on_a_branch_is_measured_against_its_branch_where_another_comes_nearer_than_the_sampling():
    # points on the curve are 0 from it, however near the other branch passes (40 um, within the 0.3 mm
    # spacing of the 20,001 samples): the nearer branch's samples are checked, not only the nearest's
    loop = _ThinLoop()
    theta = np.linspace(0.1, 6.0, 5000)
    foot = ExactContourError(loop)(loop.point(theta))
    assert_allclose(foot.distance, 0.0, atol=1e-12)


@pytest.mark.parametrize("laps", [40, 80])
def test_a_point_on_a_lead_in_is_on_it_where_the_path_then_goes_round_a_circle_many_times(laps):
    # the lead-in ends where the laps of a circle begin: near its end the laps' samples are all nearer than
    # the lead-in's own (0.13 and 0.25 mm apart), and the point is still measured against the lead-in (with
    # 80 laps the nearest sample of the lead-in's end is the circle's first, across the corner: 14 um before)
    path = ToolPath([0.0, 0.0], ["G1 X0.01 Y0"] + ["G3 X0.01 Y0 I-0.01 J0"] * laps)
    x = np.linspace(0.0095, 0.0099999, 2000)
    foot = ExactContourError(path)(np.stack([x, np.zeros_like(x)], axis=1))
    assert_allclose(foot.distance, 0.0, atol=1e-12)


@pytest.mark.parametrize("samples", [16, 23, 31, 47])
def test_points_around_a_square_corner_sampled_coarsely_get_their_exact_distance(samples):
    # two legs of 10 mm at a right angle, sampled every 0.4-1.3 mm: a point whose nearest sample is across
    # the corner is measured against its own leg, and one beyond the corner against the corner itself
    path = ToolPath([0.0, 0.0], ["G1 X0.01 Y0", "G1 X0.01 Y0.01"])
    x = np.linspace(0.008, 0.0102, 400)
    points = np.stack([x, np.zeros_like(x)], axis=1) + np.random.default_rng(1).normal(0.0, 2e-5, (400, 2))
    first = np.hypot(np.clip(points[:, 0], 0.0, 0.01) - points[:, 0], points[:, 1])
    second = np.hypot(points[:, 0] - 0.01, np.clip(points[:, 1], 0.0, 0.01) - points[:, 1])
    foot = ExactContourError(path, samples=samples)(points)
    assert_allclose(foot.distance, np.minimum(first, second), rtol=0.0, atol=1e-15)


def test_a_point_whose_foot_lies_two_samples_from_its_nearest_is_measured_there():
    # a 45-degree jog of 20 um between two long lines: for a point above the jog the nearest sample's
    # bracket misses the foot point, which lies between the next sample and the one after it
    path = ToolPath([0.0, 0.0], ["G1 X0.5 Y0", "G1 X0.50002 Y2e-5", "G1 X1 Y2e-5"])
    x = np.linspace(0.4998, 0.5002, 100)
    points = np.stack([x, np.full_like(x, 2.2989e-4)], axis=1)
    dense = path.point(np.linspace(0.495, 0.505, 40_001))
    brute = np.min(np.linalg.norm(dense[None, :, :] - points[:, None, :], axis=-1), axis=1)
    foot = ExactContourError(path)(points)
    assert np.all(foot.distance <= brute + 1e-12) and np.max(brute - foot.distance) < 1e-7


@pytest.mark.parametrize("curve, samples", [(FigureEight(0.03, 0.03), 20001), (Butterfly(0.01), 1003),
                                            (ToolPath([0.0, 0.0], ["G1 X0.01 Y0"] + ["G3 X0.01 Y0 I-0.01 J0"] * 5), 4099)])
def test_the_samples_within_a_wide_radius_found_through_the_coarse_ones_are_every_dense_one_there(curve, samples):
    # the other-branch search of a point far off the path goes through the coarse samples: it must find
    # the same dense samples as a search of them all, on a curve that crosses itself, one sampled with a
    # tail after its last coarse sample, and one gone round a circle 5 times
    solver = ExactContourError(curve, samples=samples)
    rng = np.random.default_rng(4)
    lo, hi = np.min(solver._samples, axis=0), np.max(solver._samples, axis=0)
    points = rng.uniform(lo - 0.3 * (hi - lo), hi + 0.3 * (hi - lo), (300, lo.size))
    radius = np.minimum(solver._coarse_half_spacing * 10.0 ** rng.uniform(-1.0, 2.5, 300), 0.5 * np.max(hi - lo))
    wide = radius > solver.WIDE * solver._coarse_half_spacing
    assert wide.sum() > 100 and (~wide).sum() > 10          # most through the coarse samples, some not
    rows, found = solver._dense_within(points, radius)
    distances = np.linalg.norm(solver._samples[None, :, :] - points[:, None, :], axis=-1)
    want_rows, want = np.nonzero(distances <= radius[:, None])
    assert sorted(zip(rows.tolist(), found.tolist())) == list(zip(want_rows.tolist(), want.tolist()))


def test_far_points_off_a_curve_that_crosses_itself_get_the_nearest_branch_s_distance():
    # points millimetres off a figure eight, its own crossing and its loops' insides included: the other
    # branches are looked for among the coarse samples (a far point) or through them (a wide radius), and the
    # distance is the brute-force one of a dense sampling, to the far points' documented share
    curve = FigureEight(0.03, 0.03)
    solver = ExactContourError(curve)
    rng = np.random.default_rng(5)
    points = rng.uniform([-0.1, -0.1], [0.16, 0.1], (400, 2))
    dense = curve.point(np.linspace(*curve.domain, 400001))
    brute = np.array([np.min(np.linalg.norm(dense - p, axis=1)) for p in points])
    reach = solver._nearest(points)[1]
    assert np.sum(reach > 1) > 100 and np.sum(reach == 1) > 50
    assert_allclose(solver(points).distance, brute, rtol=1e-5, atol=1e-9)


def test_power_and_atan2_of_rows_are_the_c_library_s_value_by_value():
    """numpy's own power and arctan2 (SIMD on AVX-512 builds) may part from Python's floats in the last bit;
    the batch path's forms must not."""
    from contouring_ros.core.geometry import atan2_rows, power_rows
    rng = np.random.default_rng(7)
    x, y = rng.standard_normal((5000, 1)) * 3.0, rng.standard_normal((5000, 1))
    for exponent in (2, 3):
        got = power_rows(x, exponent)
        assert got.shape == x.shape
        assert got.tolist() == [[v[0] ** exponent] for v in x.tolist()]
    assert atan2_rows(y, x).tolist() == [[math.atan2(a[0], b[0])] for a, b in zip(y.tolist(), x.tolist())]
    assert power_rows(np.array([1e200, -1e200]), 3).tolist() == [math.inf, -math.inf]
    assert power_rows(np.array([-1e200]), 2).tolist() == [math.inf]


@pytest.mark.parametrize("curve", [c for c in CURVES if c.dimension in (2, 3)], ids=lambda c: type(c).__name__)
def test_the_frame_of_one_step_is_the_frame_of_a_batch_bit_for_bit(curve):
    """frenet_axes and frenet_frame of a float parameter (a run alone) and of a batch's column (B, 1): the
    same numbers, so that a batch member runs as it would alone."""
    from contouring_ros.core.geometry import frenet_axes
    lo, hi = curve.domain
    thetas = np.linspace(lo, hi, 201)
    rates, accelerations = np.linspace(0.5, 40.0, 201), np.linspace(-30.0, 30.0, 201)
    rows = frenet_axes(curve, thetas[:, None])
    frames = frenet_frame(curve, thetas[:, None], rates[:, None], accelerations[:, None])
    for j, theta in enumerate(thetas):
        rotation, kappa, tau, speed = frenet_axes(curve, float(theta))
        np.testing.assert_array_equal(rotation, rows[0][j])
        assert (kappa, tau, speed) == (rows[1][j, 0], rows[2][j, 0], rows[3][j, 0])
        one = frenet_frame(curve, float(theta), float(rates[j]), float(accelerations[j]))
        for name in ("rotation", "rotation_rate", "rotation_acceleration", "curvature", "torsion", "speed"):
            np.testing.assert_array_equal(np.asarray(getattr(one, name)), np.asarray(getattr(frames, name))[j].reshape(
                np.shape(getattr(one, name))), err_msg=name)


def test_a_feedrate_schedule_s_one_time_is_its_array_s_bit_for_bit():
    """The reference of a run alone (a float time) and of a batch (an array of times): the same theta and
    its rates, so the same reference acceleration."""
    from contouring_ros.core.interpolation import FeedrateSchedule
    schedule = FeedrateSchedule(Butterfly(0.01), 0.0, 2 * math.pi, 0.05, 2.0, 1.0)
    times = np.linspace(0.0, schedule.duration, 3001)
    many = schedule(times[:, None])
    for k, t in enumerate(times.tolist()):
        assert tuple(float(v) for v in schedule(t)) == tuple(float(a[k, 0]) for a in many), t
