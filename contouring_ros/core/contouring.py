"""Cross-coupled contour controllers: a contour error estimate in, one correction per axis out.

The corrections add to the axes' actuator commands (see :mod:`contouring_ros.core.servo`). Every
controller's ``step`` also receives the step's reference and axis positions and velocities; those that use
them say so with ``needs_state = True`` (the CCC node then subscribes to the reference and the states).
"""
from __future__ import annotations

import numpy as np

from .curves import Curve
from .geometry import (frenet_generator, frenet_frame, left_normal, matmul, matmul_rows, matvec, matvec_rows,
                       power_rows, unit_tangent)
from .interpolation import at_reference
from .plants import coulomb_friction
from .pid import DiscretePID

__all__ = ["NoCoupling", "VariableGainCCC", "UnitVectorCCC", "TaskFramePD", "AdaptiveTNBCCC",
           "TangentialVelocityCCC"]


def per_axis(values, n: int, name: str) -> np.ndarray:
    """``values`` as a float array of one value per axis, or a ValueError naming ``name``."""
    values = np.array(np.atleast_1d(values), dtype=float)
    if values.size != n:
        raise ValueError(f"{name} needs one value per axis ({n}), got {values.size}")
    return values


class NoCoupling:
    """No cross-coupling: zero corrections (the uncoupled baseline)."""

    batchable = True

    def __init__(self, n_axes: int):
        self.n_axes = int(n_axes)

    def step(self, estimate, reference=None, position=None, velocity=None) -> np.ndarray:
        return np.zeros(self.n_axes)


class VariableGainCCC:
    """Variable-gain cross-coupled controller: Koren & Lo (1991; paper 000 Fig. 5 right) and its multi-axis
    form with C_i = n_i (Yeh & Hsu 2002; paper 004 eq. 1-11).

    The scalar contour error epsilon drives one PID G_c(s) = kp + ki/s + kd s, and its output is
    distributed to the axes with the time-varying gains C = n, the unit vector along which the estimate
    measures the error (C = E / epsilon; while epsilon = 0, the left normal of the tangent on planar
    contours, no correction in 3-D): u = C G_c(epsilon). For the tangent-line estimate on planar contours
    epsilon = C_y E_y - C_x E_x with C_x = sin(phi), C_y = cos(phi), phi the tangent angle at the reference
    point: Koren & Lo's gains for linear contours. In 3-D epsilon = |E| = <n, e> >= 0 with n the unit normal
    part of the tracking error (paper 004 eq. 7-11).
    """

    batchable = True

    def __init__(self, curve: Curve, kp: float, ki: float, kd: float, sample_time: float,
                 output_limit: float = 0.0):
        self.curve = curve
        self.pid = DiscretePID(kp, ki, kd, sample_time)
        self.output_limit = float(output_limit)

    def step(self, estimate, reference=None, position=None, velocity=None) -> np.ndarray:
        if np.ndim(estimate.signed) == 1:        # a batch: signed (B,), vectors (B, n), theta (B, 1)
            signed = estimate.signed[:, None]
            at_zero = np.abs(signed) <= 1e-12
            gains = np.divide(estimate.vector, signed, out=np.zeros_like(estimate.vector), where=~at_zero)
            if self.curve.dimension == 2 and at_zero.any():
                d1 = self.curve.derivatives(np.asarray(estimate.theta, dtype=float), order=1)[1][:, 0, :]
                gains = np.where(at_zero, left_normal(d1 / np.linalg.norm(d1, axis=-1, keepdims=True)), gains)
            return gains * self.pid.clamp(self.pid.step(signed), self.output_limit)
        if abs(estimate.signed) > 1e-12:
            gains = np.asarray(estimate.vector, dtype=float) / estimate.signed
        elif self.curve.dimension == 2:
            gains = left_normal(unit_tangent(self.curve, estimate.theta))
        else:
            gains = np.zeros(self.curve.dimension)
        return gains * self.pid.clamp(self.pid.step(estimate.signed), self.output_limit)


class UnitVectorCCC:
    """Unit-vector cross-coupled controller with one PID per axis (paper 000 eq. 15).

    The contour error vector E* = |E*| epsilon, epsilon the unit contour error vector, is resolved along
    the axes and each component E*_i drives its own PID G_i^c(s) = kp + ki/s + kd s; thanks to the
    normalisation all axes share the same gains. u_i = G_i^c(E*_i). An ``output_limit`` saturates each
    correction, with anti-windup (see :meth:`DiscretePID.clamp`); the variable-gain CCC limits G_c's output.
    """

    batchable = True

    def __init__(self, n_axes: int, kp: float, ki: float, kd: float, sample_time: float,
                 output_limit: float = 0.0):
        self.n_axes = int(n_axes)
        self.pid = DiscretePID(kp, ki, kd, sample_time)
        self.output_limit = float(output_limit)

    def step(self, estimate, reference=None, position=None, velocity=None) -> np.ndarray:
        output = self.pid.step(np.asarray(estimate.vector, dtype=float))
        return np.asarray(self.pid.clamp(output, self.output_limit), dtype=float)


class TaskFramePD:
    """Task-frame PD contour controller with feedback linearization and feedforward (paper 003 eq. 18-25).

    The axes M w'' + B w' + K F_c(w') = K u (eq. 18, friction in command units) are written in the Frenet
    frame of the reference point, f = R^T (w - w_d) (eq. 3, 19-20):
    M_F f'' + C_F f' + K_F f = K (u - u_d) - K F_c, with M_F = M R, C_F = 2 M R' + B R, K_F = M R'' + B R'
    and u_d = K^-1 (M w_d'' + B w_d'). The error states are the tangential error and the errors the
    local approximation h(t) of the contour leaves, Z1 = (t, (n, b) - h(t)), Z2 = Z1' (eq. 21). With the
    approximation's slope J = [[1, 0], [h'(t), I]] and curvature term g = (0, h''(t) t'^2),
    f' = J Z2 and f'' = J Z2' + g, so (eq. 22-23)

    u = K^-1 (M_F J V + M_F g + C_F f' + K_F f) + F_c(w') + u_d,     V = -K_P Z1 - K_D Z2      (25)

    gives the decoupled error dynamics Z1'' = V (eq. 24); K_P = diag((2 pi f)^2), K_D = diag(4 pi zeta f)
    with f = (f_t, f_n[, f_b]). ``approximation`` is the local approximation of the contour estimator
    (:func:`~contouring_ros.core.estimators.natural_local_terms` or
    :func:`~contouring_ros.core.estimators.first_order_terms`): the controller acts on the errors that
    estimator reports. M, B, K and F_c are the controller's (identified) model of the axes. The output is
    every axis' whole command: pair it with :class:`~contouring_ros.core.servo.DirectServo`.

    On a batch (positions (B, n), reference theta (B, 1); :mod:`contouring_ros.core.batch`) the same
    formulas run on each member, with the frames of :func:`~contouring_ros.core.geometry.frenet_frame`.
    """

    needs_state = True
    batchable = True

    def __init__(self, curve: Curve, approximation, mass, damping, gain, bandwidths, zeta: float = 1.0,
                 coulomb_positive=None, coulomb_negative=None):
        n = curve.dimension
        self.curve, self.approximation = curve, approximation
        self.mass, self.damping, self.gain = (per_axis(v, n, name) for v, name in (
            (mass, "mass"), (damping, "damping"), (gain, "gain")))
        self.coulomb_positive = per_axis(coulomb_positive or [0.0] * n, n, "coulomb_positive")
        self.coulomb_negative = per_axis(coulomb_negative or [0.0] * n, n, "coulomb_negative")
        if np.any(self.gain == 0.0):
            raise ValueError("the axis gains K must be non-zero (eq. 25 needs K^-1)")
        bandwidths = np.asarray(bandwidths, dtype=float)[:n]
        if bandwidths.size != n or np.any(bandwidths <= 0.0):
            raise ValueError(f"{n} positive bandwidths (f_t, f_n{', f_b' if n == 3 else ''}) are needed")
        omega = 2.0 * np.pi * bandwidths
        self.kp, self.kd = omega**2, 2.0 * float(zeta) * omega

    def step(self, estimate, reference=None, position=None, velocity=None) -> np.ndarray:
        if np.ndim(position) == 2:
            return self._step_batch(reference, position, velocity)
        frame = at_reference(reference, frenet_frame, self.curve, float(reference.theta), float(reference.theta_dot),
                             float(reference.theta_ddot))
        r, r_dot, r_ddot = frame.rotation, frame.rotation_rate, frame.rotation_acceleration
        n = r.shape[0]
        f = matvec(r.T, np.asarray(position, dtype=float) - reference.position)
        f_dot = matvec(r.T, np.asarray(velocity, dtype=float) - reference.velocity - matvec(r_dot, f))
        h, dh, ddh = self.approximation(frame.curvature, frame.torsion, f[0], n)
        z1 = np.concatenate([[f[0]], f[1:] - h])
        z2 = np.concatenate([[f_dot[0]], f_dot[1:] - dh * f_dot[0]])
        slope = np.eye(n)
        slope[1:, 0] = dh
        curvature_term = np.concatenate([[0.0], ddh * f_dot[0] ** 2])
        m, b = self.mass[:, None], self.damping[:, None]
        m_f, c_f, k_f = m * r, 2.0 * m * r_dot + b * r, m * r_ddot + b * r_dot
        v = -self.kp * z1 - self.kd * z2
        u_z = matvec(m_f, matvec(slope, v) + curvature_term) + matvec(c_f, f_dot) + matvec(k_f, f)
        feedforward = (self.mass * reference.acceleration + self.damping * reference.velocity) / self.gain
        friction = np.array([coulomb_friction(w, p, q) for w, p, q in zip(
            np.asarray(velocity, dtype=float), self.coulomb_positive, self.coulomb_negative)])
        return u_z / self.gain + friction + feedforward

    def _step_batch(self, reference, position, velocity) -> np.ndarray:
        """:meth:`step` (eq. 19-25) for a batch: the same terms, (B, n) vectors and (B, n, n) matrices."""
        frame = at_reference(reference, frenet_frame, self.curve, reference.theta, reference.theta_dot,
                             reference.theta_ddot)
        r, r_dot, r_ddot = frame.rotation, frame.rotation_rate, frame.rotation_acceleration
        b, n = position.shape
        r_t = np.swapaxes(r, -1, -2)
        f = matvec_rows(r_t, position - reference.position)
        f_dot = matvec_rows(r_t, velocity - reference.velocity - matvec_rows(r_dot, f))
        h, dh, ddh = self.approximation(frame.curvature, frame.torsion, f[:, 0:1], n)
        z1 = np.concatenate([f[:, 0:1], f[:, 1:] - h], axis=-1)
        z2 = np.concatenate([f_dot[:, 0:1], f_dot[:, 1:] - dh * f_dot[:, 0:1]], axis=-1)
        slope = np.broadcast_to(np.eye(n), (b, n, n)).copy()
        slope[:, 1:, 0] = dh
        curvature_term = np.concatenate([np.zeros((b, 1)), ddh * power_rows(f_dot[:, 0:1], 2)], axis=-1)
        m, c = self.mass[..., :, None], self.damping[..., :, None]
        m_f, c_f, k_f = m * r, 2.0 * m * r_dot + c * r, m * r_ddot + c * r_dot
        v = -self.kp * z1 - self.kd * z2
        u_z = matvec_rows(m_f, matvec_rows(slope, v) + curvature_term) + matvec_rows(c_f, f_dot) \
            + matvec_rows(k_f, f)
        feedforward = (self.mass * reference.acceleration + self.damping * reference.velocity) / self.gain
        friction = coulomb_friction(np.asarray(velocity, dtype=float), self.coulomb_positive, self.coulomb_negative)
        return u_z / self.gain + friction + feedforward


class AdaptiveTNBCCC:
    """Adaptive nonlinear contour coupling control in the tangential/normal/binormal frame (paper 001
    eq. 19-26, in the world frame as eq. 38).

    With the tracking error e~ = x_d - x, the Frenet frame F of the reference point and its rate
    dF^T/dt = v R F^T (eq. 14-15; R is the frame generator G of :func:`frenet_frame`), the filtered error of
    eq. 20 in world coordinates is r = v F R F^T e~ + e~' + alpha e~. The correction

    T_c = k_c v (F R F^T) e~ + M^ x_d'' + B^ x_d'                                         (38, terms 1 and 4)

    adds the cross-coupling term and the adaptive feedforward F Y_d theta^ = M^ x_d'' + B^ x_d' to the
    axes' PD (terms 2-3 of eq. 38, the servo law 'pid'), with one coupling gain k_c per axis as in the
    paper's experiment. The estimates of the diagonal inertia and friction follow eq. 26,
    theta^' = Gamma Y_d^T r, which in world coordinates is m^_i' = Gamma_m,i x_d,i'' r_i and
    b^_i' = Gamma_b,i x_d,i' r_i; they are integrated by a forward rectangle at each step.

    On a batch (positions (B, n), reference theta (B, 1); :mod:`contouring_ros.core.batch`) the same
    formulas run on each member and the estimates become (B, n).
    """

    needs_state = True
    batchable = True

    def __init__(self, curve: Curve, coupling, alpha: float, gamma_mass, gamma_damping, mass0, damping0,
                 sample_time: float):
        n = curve.dimension
        self.curve = curve
        self.coupling = per_axis(coupling, n, "coupling")
        self.gamma_mass = per_axis(gamma_mass, n, "gamma_mass")
        self.gamma_damping = per_axis(gamma_damping, n, "gamma_damping")
        self.mass = per_axis(mass0, n, "mass0")
        self.damping = per_axis(damping0, n, "damping0")
        self.alpha = float(alpha)
        self.sample_time = float(sample_time)

    def step(self, estimate, reference=None, position=None, velocity=None) -> np.ndarray:
        error = reference.position - np.asarray(position, dtype=float)
        error_rate = reference.velocity - np.asarray(velocity, dtype=float)
        if np.ndim(position) == 2:         # a batch: frames (B, n, n)
            frame = at_reference(reference, frenet_frame, self.curve, reference.theta, reference.theta_dot,
                                 reference.theta_ddot)
            r = frame.rotation
            generator = frenet_generator(r.shape[-1], frame.curvature, frame.torsion)
            coupled = frame.speed * matvec_rows(matmul_rows(matmul_rows(r, generator), np.swapaxes(r, -1, -2)), error)
        else:
            frame = at_reference(reference, frenet_frame, self.curve, float(reference.theta),
                                 float(reference.theta_dot), float(reference.theta_ddot))
            r = frame.rotation
            coupled = frame.speed * matvec(matmul(matmul(r, frenet_generator(r.shape[0], frame.curvature,
                                                                             frame.torsion)), r.T), error)
        filtered = coupled + error_rate + self.alpha * error
        correction = self.coupling * coupled + self.mass * reference.acceleration + self.damping * reference.velocity
        self.mass = self.mass + self.sample_time * self.gamma_mass * reference.acceleration * filtered
        self.damping = self.damping + self.sample_time * self.gamma_damping * reference.velocity * filtered
        return correction


class TangentialVelocityCCC:
    """Cross-coupled control by tangential velocity tracking (TVT, paper 002 section 3, steps 3-6).

    No axis tracks a time-stamped reference point. At the estimated foot point theta* the axes get the
    velocity command

    V = f(theta*) t(theta*) + k_c E

    with f(theta*) the feedrate the interpolator commands at that curve parameter (the curve-parameter
    velocity interpolator; never below ``min_feedrate`` until theta* reaches the end of the path: a profile
    that starts from rest has f = 0 at the start point, where the axes would otherwise stay), t the unit
    tangent there, and E the estimate's contour error vector (the normal
    from the actual point to the tangent line at the foot point, eq. 4-5 of the text's step 4): a P-type
    contour controller of gain ``kc`` [1/s] on velocity loops. The output is every axis' whole velocity
    command (servo law 'direct' over closed velocity loops).

    On a closed curve the estimator reports theta* wrapped into one period; the controller follows it
    unwrapped from the schedule's start (each step's change taken within half a period), so past
    ``theta_end`` the commanded feedrate is 0 and the axes stop at the end of the path instead of
    starting a second lap from the profile's start.

    On a batch (estimate theta (B, 1), vectors (B, n); :mod:`contouring_ros.core.batch`) the same formulas
    run on each member.
    """

    needs_state = True
    batchable = True

    def __init__(self, curve: Curve, schedule, kc: float, min_feedrate: float = 0.0):
        self.curve, self.schedule, self.kc = curve, schedule, float(kc)
        self.min_feedrate = float(min_feedrate)
        self.theta_end = float(schedule.theta_end)
        self.theta = float(schedule.theta_start)      # the foot point's parameter, unwrapped

    def step(self, estimate, reference=None, position=None, velocity=None) -> np.ndarray:
        if np.ndim(estimate.theta):
            return self._step_batch(estimate)
        theta = float(estimate.theta)
        tangent = unit_tangent(self.curve, theta)
        if self.curve.closed:
            lo, hi = self.curve.domain
            period = hi - lo
            self.theta += (theta - self.theta + 0.5 * period) % period - 0.5 * period
            theta = self.theta
        feedrate = float(self.schedule.feedrate_at(self.curve, theta))
        if theta < self.theta_end:
            feedrate = max(feedrate, self.min_feedrate)
        return feedrate * tangent + self.kc * np.asarray(estimate.vector, dtype=float)

    def _step_batch(self, estimate) -> np.ndarray:
        """:meth:`step` for a batch: foot points theta (B, 1), error vectors (B, n)."""
        theta = np.asarray(estimate.theta, dtype=float)
        tangent = unit_tangent(self.curve, theta)[:, 0, :]
        if self.curve.closed:
            lo, hi = self.curve.domain
            period = hi - lo
            self.theta = self.theta + (np.mod(theta - self.theta + 0.5 * period, period) - 0.5 * period)
            theta = self.theta
        feedrate = self.schedule.feedrate_at(self.curve, theta)
        feedrate = np.where(theta < self.theta_end, np.maximum(feedrate, self.min_feedrate), feedrate)
        return feedrate * tangent + self.kc * estimate.vector
