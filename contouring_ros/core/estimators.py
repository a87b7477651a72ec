"""Contour error estimators.

Every estimator has the same step: the reference at step k and the measured axis positions at k give a
:class:`ContourEstimate` (estimated foot-point parameter, error vector E = R(theta_hat) - P, signed scalar).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import kernels
from .curves import Curve
from .foot_point import foot_point_flow, foot_point_flow_planar
from .geometry import atan2_rows, dot, dot_rows, frenet_axes, left_normal, matvec, matvec_rows, norm, power_rows, signed_error
from .interpolation import at_reference

__all__ = ["ContourEstimate", "TangentLineEstimator", "NewtonEstimator", "BranchCheck", "LocalApproximationEstimator",
           "NaturalLocalEstimator", "OsculatingCircleEstimator", "FootPointSearchEstimator", "first_order_terms",
           "natural_local_terms"]


@dataclass(frozen=True)
class ContourEstimate:
    """One step's contour error estimate.

    Attributes
    ----------
    theta : float
        Estimated foot-point parameter theta_hat.
    vector : ndarray, shape (n,)
        Estimated contour error vector, from the actual position to the estimated foot point [m].
    signed : float
        Signed scalar contour error [m] (see :func:`contouring_ros.core.geometry.signed_error`).
    """

    theta: float
    vector: np.ndarray
    signed: float


class TangentLineEstimator:
    """Static tangent-line estimate (Koren & Lo; paper 000 eq. 5-7).

    The contour is replaced by its tangent line at the current reference point R(theta_r). With the
    tracking error E = R(theta_r) - P and the unit tangent t there, the estimate is the part of E normal
    to the tangent, E - (E.t) t, and the foot point on the tangent line lies at
    theta_r - (E.t) / |R'(theta_r)|.
    """

    #: has a batch path, :meth:`step_batch` (:mod:`contouring_ros.core.batch`)
    batchable = True

    def __init__(self, curve: Curve):
        self.curve = curve

    def step_batch(self, reference, position) -> ContourEstimate:
        """:meth:`step` for a batch: reference arrays (B, n) and theta (B, 1), positions (B, n)."""
        return self.step(reference, position)

    def step(self, reference, position) -> ContourEstimate:
        if np.ndim(position) == 2:
            d = at_reference(reference, _batch_derivatives, self.curve, reference.theta, 1)
            speed = np.linalg.norm(d[1], axis=-1, keepdims=True)
            tangent = d[1] / speed
            tracking = d[0] - position
            along = np.sum(tracking * tangent, axis=-1, keepdims=True)
            vector = tracking - along * tangent
            return ContourEstimate(theta=reference.theta - along / speed, vector=vector,
                                   signed=signed_error(vector, tangent))
        d = at_reference(reference, self.curve.derivatives, reference.theta, 1)
        speed = norm(d[1])
        tangent = d[1] / speed
        tracking = d[0] - position
        along = dot(tracking, tangent)
        vector = tracking - along * tangent
        return ContourEstimate(theta=float(reference.theta) - along / speed, vector=vector,
                               signed=float(signed_error(vector, tangent)))


def _batch_derivatives(curve: Curve, theta, order: int) -> tuple:
    """R and its derivatives at a batch of parameters theta (B, 1): order + 1 arrays (B, n)."""
    return tuple(curve.derivatives(np.asarray(theta, dtype=float), order=order)[:, :, 0, :])


class BranchCheck:
    """Bounded global check of a local foot-point estimate (paper 000, Remark 3 and Fig. 3).

    A local estimate iterated from the previous step's foot point can settle on the wrong branch near a
    cusp or a tight curve. The check compares the estimate's distance |R(theta_hat) - P| with the distance
    to the nearest of ``samples`` points spread over the whole curve; if the estimate is farther by more
    than ``tolerance``, it returns that sample's parameter to restart from.
    """

    #: has a batch path, :meth:`restart_batch` (:mod:`contouring_ros.core.batch`)
    batchable = True

    def __init__(self, curve: Curve, samples: int, tolerance: float):
        lo, hi = curve.domain
        self.grid = np.linspace(lo, hi, int(samples))
        self.points = curve.point(self.grid)
        self.tolerance = float(tolerance)

    def restart_batch(self, distance, position):
        """:meth:`restart` for a batch: distances (B, 1), positions (B, n). Returns None when no estimate
        is on a wrong branch, else the parameters to restart from (B, 1) and where to restart (B, 1)."""
        over = np.flatnonzero(distance[:, 0] > self.tolerance)
        if not over.size:                           # as in restart: no sample can be nearer by more
            return None
        # the members whose distance is over the tolerance alone (the others cannot restart)
        points = self.points[over] if self.points.ndim == 3 else self.points[None]
        squared = np.sum((points - position[over, None, :]) ** 2, axis=-1)
        nearest = np.argmin(squared, axis=1)[:, None]
        closest = np.sqrt(np.take_along_axis(squared, nearest, axis=1))
        grid = self.grid[over] if self.grid.ndim == 2 else self.grid
        start = np.zeros(distance.shape)
        start[over] = np.take_along_axis(np.broadcast_to(grid, squared.shape), nearest, axis=1)
        restart = np.zeros(distance.shape, dtype=bool)
        restart[over] = distance[over] > closest + self.tolerance
        return start, restart

    def restart(self, distance: float, position) -> float | None:
        """The parameter to restart from, or None when the estimate is on the nearest branch."""
        if distance <= self.tolerance:      # no sample can be nearer by more than the tolerance
            return None
        squared = np.sum((self.points - position) ** 2, axis=1)
        nearest = int(np.argmin(squared))
        if distance > math.sqrt(squared[nearest]) + self.tolerance:
            return float(self.grid[nearest])
        return None


class NewtonEstimator:
    """Newton-based dynamic contour error estimate (paper 000 eq. 8-14).

    d theta_hat / dt = -k' g / h with g = E^T R' (9) and h ~= |R'|^2 (11), E = R(theta_hat) - P (4). The
    ratio g / h passes through a first-order low-pass filter of bandwidth c' before the integrator
    (the "linear estimator" of Fig. 2). Within each control step the filter and the integrator are
    advanced by ``inner_step`` at a time (filter exact under a zero-order hold, integrator by one
    rectangle), starting from the previous step's final estimate and filter state (Remark 3): the Newton
    flow runs on its own fast time scale so that theta_hat settles on the moving foot point within the
    step.

    Stopping rule. The flow is iterated until it has converged, at most ``max_iterations`` times a step.
    An iterate theta_n is the step's estimate when both, in metres, are within ``tolerance``:

    - the tangential residual at theta_n, |E^T R'| / |R'| = |E^T U| (eq. 9, 14): the part of
      R(theta_n) - P along the tangent, zero exactly at a foot point (eq. 14: the flow stops where
      E^T U = 0) and, to first order, the distance along the contour from R(theta_n) to the foot point.
      At an end of an open contour where the flow pushes past the end, the end is the foot point and the
      residual counts as zero;
    - the step the flow would take next, |theta_{n+1} - theta_n| |R'(theta_n)| (the filtered update (8)
      with g of (9) and h of (11), clipped at the ends of an open contour): the filter state has decayed
      too, so the estimate is at rest.

    Both are needed because the filtered flow is second order (filter and integrator; with k' = c' = 500
    and a 1 ms inner step its poles are complex, |z| = exp(-c' dt / 2) = 0.78 per iteration): theta_n
    passes through the foot point while the filter still carries it on, and pauses at each turn away
    from it. A converged estimate lies within ``tolerance`` of a foot point along the contour, so its
    error vector's length is the exact contour error to second order in that offset (to within
    ``tolerance`` at worst, for a point on the contour). The update that would follow is not applied: the
    filter keeps its state for the next step. A step whose ``max_iterations``-th update still leaves an
    unconverged iterate keeps that iterate and is counted in ``cap_reached``.

    Parameters
    ----------
    curve : Curve
    k_prime : float
        Adaptation gain k' [1/s].
    c_prime : float
        Filter bandwidth c' [rad/s].
    theta0 : float
        Initial estimate (paper: theta_0 = -a_r, the start of the contour).
    inner_step : float
        Time step of one inner iteration [s].
    tolerance : float
        Convergence tolerance [m] (see above).
    max_iterations : int
        Most inner iterations per control step.
    branch_check : BranchCheck, optional
        Global check after each step; when it finds a nearer branch the estimate restarts there
        (counted in ``recoveries``).

    Attributes
    ----------
    iterations : int
        Inner iterations of the last step (of its restart, when it restarted).
    cap_reached : int
        Steps whose estimate reached ``max_iterations`` without converging.
    recoveries : int
        Restarts by the branch check.

    On a batch (:meth:`step_batch`) the three counts are arrays (B, 1), one per member.
    """

    #: has a batch path, :meth:`step_batch` (:mod:`contouring_ros.core.batch`)
    batchable = True

    #: the batch size from which the pure path's batch iteration costs less than the runs one by one: a batch
    #: step iterates until its slowest member has converged (39-42 iterations a step on paper 000's files),
    #: each iteration a few numpy calls whose cost hardly depends on the batch size (bench/batch_speed.py
    #: --batch N on this 2-core machine: the default experiment breaks even at 16 members, a butterfly at
    #: about 10)
    PURE_BATCH_MINIMUM = 12
    #: ... and with the compiled kernel (core/kernels.py), which iterates member by member: the loop around
    #: it is the batch's gain (bench/batch_speed.py --only default --batch N, 1 s, Intel Xeon 2-core host:
    #: 0.6x the runs one by one at 2 members, 1.1x at 4, 1.9x at 8)
    COMPILED_BATCH_MINIMUM = 4

    def __init__(self, curve: Curve, k_prime: float, c_prime: float, theta0: float, inner_step: float,
                 tolerance: float = 1e-9, max_iterations: int = 200, branch_check: BranchCheck | None = None):
        self.curve = curve
        self.k_prime, self.c_prime = float(k_prime), float(c_prime)
        self.inner_step = float(inner_step)
        self.tolerance = float(tolerance)
        self.max_iterations = int(max_iterations)
        if not self.tolerance > 0.0 or self.max_iterations < 1:
            raise ValueError("the Newton estimate needs tolerance > 0 and max_iterations >= 1")
        self._tolerance_squared = self.tolerance * self.tolerance
        self._filter_decay = math.exp(-self.c_prime * self.inner_step)
        self._gain = self.k_prime * self.inner_step
        self.theta = float(theta0)
        self.filtered = 0.0
        self.branch_check = branch_check
        self.recoveries = 0
        self.cap_reached = 0
        self.iterations = 0

    @property
    def batch_minimum(self) -> int:
        """:data:`COMPILED_BATCH_MINIMUM` where the flow runs compiled for this curve (numba on, the curve
        with a formula: core/kernels.py), else :data:`PURE_BATCH_MINIMUM`. Only the speed depends on it: a
        member of a batch has the numbers of its run alone, bit for bit, compiled or not
        (tests/core/test_kernels.py, tests/core/test_batch.py)."""
        compiled = kernels.ENABLED and kernels.formula_of(self.curve) is not None
        return self.COMPILED_BATCH_MINIMUM if compiled else self.PURE_BATCH_MINIMUM

    def step(self, reference, position) -> ContourEstimate:
        capped = self._iterate(position)
        d = self.curve.derivatives(self.theta, order=1)
        vector = d[0] - np.asarray(position)
        if self.branch_check is not None:
            restart = self.branch_check.restart(norm(vector), position)
            if restart is not None:
                self.recoveries += 1
                self.theta, self.filtered = restart, 0.0
                capped = self._iterate(position)
                d = self.curve.derivatives(self.theta, order=1)
                vector = d[0] - np.asarray(position)
        if capped:
            self.cap_reached += 1
        tangent = d[1] / norm(d[1])
        return ContourEstimate(theta=self.theta, vector=vector, signed=float(signed_error(vector, tangent)))

    def step_batch(self, reference, position) -> ContourEstimate:
        """:meth:`step` for a batch: positions (B, n); theta_hat (B, 1). Each member iterates until its own
        convergence or cap (then stops changing), as it would alone."""
        capped = self._iterate_batch(position)
        d = _batch_derivatives(self.curve, self.theta, 1)
        vector = d[0] - position
        if self.branch_check is not None:
            distance = np.linalg.norm(vector, axis=-1, keepdims=True)
            found = self.branch_check.restart_batch(distance, position)
            start, restart = found if found is not None else (None, np.zeros(distance.shape, dtype=bool))
            if restart.any():
                self.recoveries = self.recoveries + restart
                kept = self.theta, self.filtered, self.iterations
                self.theta = np.where(restart, start, self.theta)
                self.filtered = np.where(restart, 0.0, self.filtered)
                capped = np.where(restart, self._iterate_batch(position, restart), capped)
                self.iterations = np.where(restart, self.iterations, kept[2])
                d = _batch_derivatives(self.curve, self.theta, 1)
                vector = d[0] - position
        self.cap_reached = self.cap_reached + capped
        tangent = d[1] / np.linalg.norm(d[1], axis=-1, keepdims=True)
        return ContourEstimate(theta=self.theta, vector=vector, signed=signed_error(vector, tangent))

    def _iterate(self, position) -> bool:
        """Advance the filtered Newton flow from the current estimate until it has converged (see the class
        docstring) or made ``max_iterations`` updates; one position (n,). Returns whether the cap was
        reached without converging. The flow is :func:`~contouring_ros.core.foot_point.foot_point_flow_planar`
        (an open planar curve) or :func:`~contouring_ros.core.foot_point.foot_point_flow`, compiled where numba
        allows (core/kernels.py)."""
        curve, closed, (lo, hi) = self.curve, self.curve.closed, self.curve.domain
        decay, gain, tolerance2, cap = self._filter_decay, self._gain, self._tolerance_squared, self.max_iterations
        coordinates, blend, theta, filtered = [float(p) for p in position], 1.0 - decay, self.theta, self.filtered
        compiled = kernels.newton_flow(curve) if len(coordinates) == curve.dimension else None
        if compiled is not None:
            result = compiled(position, float(theta), float(filtered), decay, blend, gain, tolerance2, cap)
        elif len(coordinates) == 2 and not closed:
            result = foot_point_flow_planar(curve, *coordinates, theta, filtered, decay, blend, gain, tolerance2, cap, lo, hi)
        else:
            result = foot_point_flow(curve, coordinates, theta, filtered, decay, blend, gain, tolerance2, cap, lo, hi, closed)
        self.theta, self.filtered, self.iterations, converged = result
        return not converged

    def _iterate_batch(self, position, active=None):
        """:meth:`_iterate` for a batch of positions (B, n) with estimates (B, 1): each member (of those
        ``active``, (B, 1) bool, default all) iterates until its own convergence or cap, then keeps its
        estimate and filter state while the rest go on. Returns the members that reached their cap without
        converging, (B, 1) bool. (The tests are gated so that an iteration where no member can stop costs
        little more than the update itself.)"""
        curve = self.curve
        b = position.shape[0]
        compiled = kernels.newton_flow_batch(
            curve, position, self.theta, self.filtered, self._filter_decay, 1.0 - self._filter_decay, self._gain,
            self._tolerance_squared, self.max_iterations, active,
            self.__dict__.setdefault("_flow_constants", {}))      # a batch's own object: its columns, made once
        if compiled is not None:                       # the same steps, compiled (core/kernels.py)
            self.theta, self.filtered, self.iterations, capped = compiled
            return capped
        theta = np.broadcast_to(self.theta, (b, 1)).astype(float)
        filtered = np.broadcast_to(self.filtered, (b, 1)).astype(float)
        decay, gain, tolerance2, cap = self._filter_decay, self._gain, self._tolerance_squared, self.max_iterations
        blend, first_cap = 1.0 - decay, np.min(cap)
        coordinates = [position[:, i:i + 1] for i in range(position.shape[1])]
        columns, closed, (lo, hi) = curve.columns, curve.closed, curve.domain
        active = np.ones((b, 1), dtype=bool) if active is None else active
        running, converged = active.copy(), np.zeros((b, 1), dtype=bool)
        everyone = bool(running.all())           # while true, updates need no masking
        iterations = np.zeros((b, 1), dtype=int)
        n = 0
        while True:
            point, tangent = columns(theta)[:2]
            (r, *rs), (p, *ps), (t, *ts) = point, coordinates, tangent
            gradient, hessian = (r - p) * t, t * t          # g = E^T R' (eq. 9), h ~= |R'|^2 (eq. 11)
            for r, p, t in zip(rs, ps, ts):
                gradient = gradient + (r - p) * t
                hessian = hessian + t * t
            following = decay * filtered + blend * (gradient / hessian)
            if closed:
                moved = -gain * following
                new = lo + np.mod(theta + moved - lo, hi - lo)
            else:
                new = np.minimum(np.maximum(theta - gain * following, lo), hi)
                moved = new - theta
            near = gradient * gradient <= tolerance2 * hessian
            if not closed:
                ends = (theta == lo) | (theta == hi)
                if ends.any():
                    near = near | ((theta == lo) & (gradient > 0.0)) | ((theta == hi) & (gradient < 0.0))
            stopped = False
            if near.any():
                done = near & (moved * moved * hessian <= tolerance2)
                if done.any():
                    converged |= running & done
                    running &= ~done
                    stopped = True
            if n >= first_cap:
                running &= iterations < cap
                stopped = True
            if stopped:
                everyone = False
                if not running.any():
                    break
            if everyone:
                theta, filtered = new, following
            else:
                theta = np.where(running, new, theta)
                filtered = np.where(running, following, filtered)
            iterations += running
            n += 1
        self.theta, self.filtered, self.iterations = theta, filtered, iterations
        return active & ~converged


def first_order_terms(kappa: float, tau: float, t: float, n: int) -> tuple:
    """The tangent line in Frenet coordinates (paper 003 eq. 11): h(t) = 0, so the estimated contour error is
    the normal (and binormal) part of the tracking error. Returns (h, dh/dt, d2h/dt2), each of length n - 1
    (for a batch, t (B, 1): each (B, n - 1))."""
    zero = np.zeros(np.shape(t)[:-1] + (n - 1,)) if np.ndim(t) else np.zeros(n - 1)
    return zero, zero, zero


def natural_local_terms(kappa: float, tau: float, t: float, n: int) -> tuple:
    """The natural local (cubic) approximation in Frenet coordinates (paper 003 eq. 10, 13-14):
    n = kappa t^2 / 2 and, in 3-D, b = kappa tau t^3 / 6. Returns (h, dh/dt, d2h/dt2) at t (for a batch,
    kappa, tau and t (B, 1): each (B, n - 1), the same formulas elementwise)."""
    if np.ndim(t):
        kappa, tau, t = np.broadcast_arrays(kappa, tau, t)
        if n == 2:
            return 0.5 * kappa * t * t, kappa * t, kappa
        return (np.concatenate([0.5 * kappa * t * t, kappa * tau * power_rows(t, 3) / 6.0], axis=-1),
                np.concatenate([kappa * t, 0.5 * kappa * tau * t * t], axis=-1),
                np.concatenate([kappa, kappa * tau * t], axis=-1))
    if n == 2:
        return np.array([0.5 * kappa * t * t]), np.array([kappa * t]), np.array([kappa])
    return (np.array([0.5 * kappa * t * t, kappa * tau * t**3 / 6.0]),
            np.array([kappa * t, 0.5 * kappa * tau * t * t]), np.array([kappa, kappa * tau * t]))


class LocalApproximationEstimator:
    """Contour error from a local approximation of the contour in the Frenet frame at the reference point.

    With f = R^T (P - w_d) = (t, n[, b]) the actual position in the Frenet frame of the reference point
    (paper 003 eq. 3) and the approximation h(t) of the contour there, the estimated errors are
    z = (n, b) - h(t) (eq. 15-16) and the estimate's error vector is E = -(beta z_n + gamma z_b), from the
    actual position to the point of the approximation with the same tangential coordinate. That point's
    parameter is reported as theta_r + t / |R'(theta_r)|.

    ``approximation`` is :func:`first_order_terms` (the tangent line: the estimate is the tracking error's
    normal part, identical to :class:`TangentLineEstimator`) or :func:`natural_local_terms` (paper 003).
    """

    #: has a batch path, :meth:`step_batch` (:mod:`contouring_ros.core.batch`)
    batchable = True

    def __init__(self, curve: Curve, approximation=None):
        self.curve = curve
        self.approximation = approximation or natural_local_terms

    def task_errors(self, reference, position) -> tuple:
        """(f, z, R, kappa, tau, |R'|): Frenet coordinates of the position, the estimated errors z and the frame
        (for a batch of positions (B, n): f (B, n), z (B, n - 1), R (B, n, n), the scalars (B, 1))."""
        if np.ndim(position) == 2:
            rotation, kappa, tau, speed = at_reference(reference, frenet_axes, self.curve, reference.theta)
            f = matvec_rows(np.swapaxes(rotation, -1, -2), position - reference.position)
            h, _, _ = self.approximation(kappa, tau, f[:, 0:1], rotation.shape[-1])
            return f, f[:, 1:] - h, rotation, kappa, tau, speed
        rotation, kappa, tau, speed = at_reference(reference, frenet_axes, self.curve, reference.theta)
        f = matvec(rotation.T, np.asarray(position, dtype=float) - reference.position)
        h, _, _ = self.approximation(kappa, tau, f[0], rotation.shape[0])
        return f, f[1:] - h, rotation, kappa, tau, speed

    def step(self, reference, position) -> ContourEstimate:
        f, z, rotation, _, _, speed = self.task_errors(reference, position)
        vector = -matvec(rotation[:, 1:], z)
        return ContourEstimate(theta=float(reference.theta) + float(f[0]) / speed, vector=vector,
                               signed=float(signed_error(vector, rotation[:, 0])))

    def step_batch(self, reference, position) -> ContourEstimate:
        """:meth:`step` for a batch: reference arrays (B, n) and theta (B, 1), positions (B, n); the same
        formulas on each member (frames of :func:`~contouring_ros.core.geometry.frenet_axes`)."""
        f, z, rotation, _, _, speed = self.task_errors(reference, position)
        vector = -matvec_rows(rotation[:, :, 1:], z)
        return ContourEstimate(theta=reference.theta + f[:, 0:1] / speed, vector=vector,
                               signed=signed_error(vector, rotation[:, :, 0]))


class NaturalLocalEstimator(LocalApproximationEstimator):
    """Natural local approximation estimate of paper 003 (eq. 10-17): the contour near the reference
    point replaced by the cubic with its curvature, torsion and Frenet frame."""

    def __init__(self, curve: Curve):
        super().__init__(curve, natural_local_terms)


class OsculatingCircleEstimator:
    """Osculating-circle (circular approximation) estimate of Yang & Li (2011; paper 003 eq. 12).

    The planar contour near the reference point R(theta_r) is replaced by its osculating circle: centre
    c = R + beta / kappa (beta the left normal, kappa the signed curvature, paper 003 eq. 27), radius
    1 / |kappa|. The estimate is the distance to that circle, E = c + (P - c) / |P - c| / |kappa| - P, and
    its foot point's parameter is theta_r + phi / (|kappa| |R'|), phi the signed angle from R - c to P - c
    seen in the direction of travel. Exact on circles; where kappa vanishes it is the tangent-line estimate.
    """

    #: has a batch path, :meth:`step_batch` (:mod:`contouring_ros.core.batch`)
    batchable = True

    def __init__(self, curve: Curve, min_curvature: float = 1e-9):
        if curve.dimension != 2:
            raise ValueError("the osculating-circle estimate is defined for planar (2-axis) contours")
        self.curve = curve
        self.min_curvature = float(min_curvature)
        self._tangent_line = TangentLineEstimator(curve)

    def step(self, reference, position) -> ContourEstimate:
        rotation, kappa, _, speed = at_reference(reference, frenet_axes, self.curve, reference.theta)
        if abs(kappa) < self.min_curvature:
            return self._tangent_line.step(reference, position)
        point = np.asarray(position, dtype=float)
        centre = reference.position + rotation[:, 1] / kappa
        radial = point - centre
        distance = norm(radial)
        vector = centre + radial / (distance * abs(kappa)) - point
        start = reference.position - centre
        angle = math.atan2(start[0] * radial[1] - start[1] * radial[0], dot(start, radial))
        theta = float(reference.theta) + math.copysign(1.0, kappa) * angle / (abs(kappa) * speed)
        foot_tangent = math.copysign(1.0, kappa) * left_normal(radial / distance)
        return ContourEstimate(theta=theta, vector=vector, signed=float(signed_error(vector, foot_tangent)))

    def step_batch(self, reference, position) -> ContourEstimate:
        """:meth:`step` for a batch: reference arrays (B, 2) and theta (B, 1), positions (B, 2); the same
        formulas elementwise (the frame of :func:`~contouring_ros.core.geometry.frenet_axes`), the
        tangent-line estimate where the curvature vanishes."""
        d = at_reference(reference, _batch_derivatives, self.curve, reference.theta, 2)
        d1, d2 = d[1], d[2]
        speed = np.sqrt(np.sum(d1 * d1, axis=-1, keepdims=True))
        kappa = (d1[:, 0:1] * d2[:, 1:2] - d1[:, 1:2] * d2[:, 0:1]) / power_rows(speed, 3)
        straight = np.abs(kappa) < self.min_curvature
        with np.errstate(divide="ignore", invalid="ignore"):
            centre = reference.position + left_normal(d1 / speed) / kappa
            radial = position - centre
            distance = np.sqrt(dot_rows(radial, radial))[:, None]
            vector = centre + radial / (distance * np.abs(kappa)) - position
            start = reference.position - centre
            angle = atan2_rows(start[:, 0:1] * radial[:, 1:2] - start[:, 1:2] * radial[:, 0:1],
                               np.sum(start * radial, axis=-1, keepdims=True))
            theta = reference.theta + np.copysign(1.0, kappa) * angle / (np.abs(kappa) * speed)
            signed = signed_error(vector, np.copysign(1.0, kappa) * left_normal(radial / distance))
        if straight.any():
            line = self._tangent_line.step_batch(reference, position)
            vector, theta = np.where(straight, line.vector, vector), np.where(straight, line.theta, theta)
            signed = np.where(straight[:, 0], line.signed, signed)
        return ContourEstimate(theta=theta, vector=vector, signed=signed)


class FootPointSearchEstimator:
    """Foot-point search by tangential-error backstepping, and the distance to the tangent line there
    (paper 002, section 3, steps 1-4; its reference 20).

    From the previous step's foot point (the reference point at the first step) the parameter steps back by
    the tangential error, theta <- theta + <P - R(theta), t(theta)> / |R'(theta)|, until that error is
    below ``tolerance`` [m] or after ``max_iterations`` backsteps (paper 002: 10 iterations, 1 um); at an
    end of an open contour where the backstep points past the end (the clipped step stays put) the end is
    the foot point and the search stops there too. The estimate is the normal part of R(theta*) - P: the
    distance from P to the tangent line at the foot point, exact at a true foot point.

    Attributes
    ----------
    iterations : int
        Backsteps of the last step.
    cap_reached : int
        Steps that made ``max_iterations`` backsteps and still missed the tolerance.

    On a batch (:meth:`step_batch`) the two counts are arrays (B, 1), one per member.
    """

    #: has a batch path, :meth:`step_batch` (:mod:`contouring_ros.core.batch`)
    batchable = True

    def __init__(self, curve: Curve, max_iterations: int = 10, tolerance: float = 1e-6):
        self.curve = curve
        self.max_iterations = int(max_iterations)
        self.tolerance = float(tolerance)
        self.theta = None
        self.iterations = 0
        self.cap_reached = 0

    def step(self, reference, position) -> ContourEstimate:
        point = np.asarray(position, dtype=float)
        theta = float(reference.theta) if self.theta is None else self.theta
        self.iterations = 0
        while True:
            d = self.curve.derivatives(theta, order=1)
            speed = norm(d[1])
            tangent = d[1] / speed
            along = dot(point - d[0], tangent)
            if abs(along) < self.tolerance:
                break
            if self.iterations >= self.max_iterations:
                self.cap_reached += 1
                break
            new = self.curve.wrap_scalar(theta + along / speed)
            if new == theta and not self.curve.closed:      # clipped at an end: the end is the foot point
                break
            theta = new
            self.iterations += 1
        self.theta = theta
        vector = d[0] - point + along * tangent
        return ContourEstimate(theta=theta, vector=vector, signed=float(signed_error(vector, tangent)))

    def step_batch(self, reference, position) -> ContourEstimate:
        """:meth:`step` for a batch: reference theta (B, 1), positions (B, n). The members backstep together,
        one array operation per backstep; each stops at its own tolerance, cap or end of the contour and then
        keeps its foot point while the rest go on, as it would alone."""
        curve = self.curve
        b = position.shape[0]
        theta = np.broadcast_to(reference.theta if self.theta is None else self.theta, (b, 1)).astype(float)
        iterations = np.zeros((b, 1), dtype=int)
        capped = np.zeros((b, 1), dtype=bool)
        running = np.ones((b, 1), dtype=bool)
        while True:
            d = _batch_derivatives(curve, theta, 1)
            speed = np.sqrt(dot_rows(d[1], d[1]))[:, None]
            tangent = d[1] / speed
            along = dot_rows(position - d[0], tangent)[:, None]
            running &= ~(np.abs(along) < self.tolerance)
            cap = running & (iterations >= self.max_iterations)
            capped |= cap
            running &= ~cap
            new = curve.wrap(theta + along / speed)
            if not curve.closed:
                running &= new != theta       # clipped at an end: the end is the foot point
            if not running.any():
                break
            theta = np.where(running, new, theta)
            iterations += running
        self.theta, self.iterations = theta, iterations
        self.cap_reached = self.cap_reached + capped
        vector = d[0] - position + along * tangent
        return ContourEstimate(theta=theta, vector=vector, signed=signed_error(vector, tangent))
