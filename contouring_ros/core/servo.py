"""Per-axis position servo laws.

Every law has the same step: the axis reference (position, velocity, acceleration), the axis state
(position, velocity) and the cross-coupled correction at step k give the actuator command at k. The
correction adds to the command (Koren's cross-coupling structure; paper 000 Fig. 5).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm

from .geometry import matvec
from .pid import DiscretePID
from .plants import coulomb_friction, has_limit, symmetric_clip

__all__ = ["PIDFeedforwardServo", "IntegralSlidingModeServo", "DisturbanceObserver", "DirectServo",
           "ExtendedStateObserver", "ESOSlidingModeServo", "PIDServo", "CascadeServo", "saturation"]


def saturation(u: float) -> float:
    """sat(u) = u for |u| <= 1, sign(u) otherwise (paper 000, after eq. 20); elementwise on arrays."""
    return np.clip(u, -1.0, 1.0) if isinstance(u, np.ndarray) else max(-1.0, min(1.0, u))


def _inverse_first_order(ref_vel: float, ref_acc: float, gain: float, time_constant: float) -> float:
    """Command that makes a first-order velocity axis follow the reference: (tau R'' + R') / k."""
    return (time_constant * ref_acc + ref_vel) / gain


class PIDFeedforwardServo:
    """PID on the position error plus reference feedforward (paper 000 section IV-A).

    T = PID(R - P) + (tau R'' + R') / k + correction; the derivative term uses the velocity error R' - V.

    Parameters
    ----------
    kp, ki, kd : float
        PID gains, e.g. PID_1 = 8.08 + 93.2/s + 0.24 s.
    gain, time_constant : float
        The axis model used by the feedforward (k, tau of eq. 2).
    sample_time : float
        Ts [s].
    """

    batchable = True

    def __init__(self, kp, ki, kd, gain, time_constant, sample_time, output_limit: float = 0.0):
        self.pid = DiscretePID(kp, ki, kd, sample_time)
        self.gain = float(gain)
        self.time_constant = float(time_constant)
        self.output_limit = float(output_limit)

    def step(self, ref_pos, ref_vel, ref_acc, position, velocity, correction) -> float:
        feedback = self.pid.step(ref_pos - position, ref_vel - velocity)
        command = feedback + _inverse_first_order(ref_vel, ref_acc, self.gain, self.time_constant) + correction
        return self.pid.clamp(command, self.output_limit)


class DisturbanceObserver:
    """Adaptive disturbance estimate of paper 000 eq. 24-26.

    dOmega/dt = -c Omega - c V                       (24)
    xi        = (tau / k) c (Omega + V) + V / k - T   (25)
    dDelta/dt = -d Delta + d xi                       (26)

    c (Omega + V) = c s / (s + c) V is the filtered velocity derivative; the factor c in (25), lost in the
    paper's text, is restored so that xi equals D for the model (2) at constant acceleration. Under a jerk J
    (a jerk-limited feed plan) eq. 25 pairs the filtered derivative with the unfiltered command and reads
    xi - D = (tau / k) (c s / (s + c) - s) V, about -(tau / k) J / c, as load.

    ``plan_correction`` (not in the paper): xi gains (tau / k) (R'' - c s / (s + c) R'), the same filter
    mismatch computed on the reference the axis follows (Omega_R: eq. 24 driven by R'), which cancels the
    jerk term as far as V follows R' and is zero at constant acceleration. Unlike a Q-filter observer
    (the filter on T too), D itself still enters xi unfiltered, so a load is taken up as fast as with (25).

    Both filters are discretised exactly under a zero-order hold. T is the command applied over the
    previous step. The filters start in the steady state of a motion with the given initial velocity and
    acceleration and no disturbance.
    """

    batchable = True

    def __init__(self, c, d, gain, time_constant, sample_time, velocity=0.0, acceleration=0.0,
                 plan_correction: bool = False):
        self.c, self.d = float(c), float(d)
        self.gain, self.time_constant = float(gain), float(time_constant)
        self._omega_decay = math.exp(-self.c * sample_time)
        self._delta_decay = math.exp(-self.d * sample_time)
        self.omega = -float(velocity) + float(acceleration) / self.c
        self.estimate = 0.0
        self.previous_command = _inverse_first_order(velocity, acceleration, self.gain, self.time_constant)
        self.plan_correction = bool(plan_correction)
        self.reference_omega = self.omega         # Omega_R: eq. 24 on the reference velocity

    def update(self, velocity: float, ref_vel=0.0, ref_acc=0.0) -> float:
        """Return the estimate Delta_k and advance the filters with this step's velocity (and, with
        ``plan_correction``, the reference velocity and acceleration)."""
        estimate = self.estimate
        lag = self.time_constant / self.gain
        xi = lag * self.c * (self.omega + velocity) + velocity / self.gain - self.previous_command
        self.omega = self._omega_decay * self.omega - (1.0 - self._omega_decay) * velocity
        if self.plan_correction:
            xi = xi + lag * (ref_acc - self.c * (self.reference_omega + ref_vel))
            self.reference_omega = self._omega_decay * self.reference_omega - (1.0 - self._omega_decay) * ref_vel
        self.estimate = self._delta_decay * estimate + (1.0 - self._delta_decay) * xi
        return estimate


class IntegralSlidingModeServo:
    """Integral sliding mode control with saturation (paper 000 eq. 16-23), optional eq. 24-26 compensation.

    sigma = V~ + a P~ + b q                                                         (21)
    dq/dt = -b q + mu sat(sigma / mu)                                              (20)
    T'    = ((a + b) tau - 1) / k V~ + a b tau / k P~ + tau / k R'' + R' / k + kappa mu sat(sigma / mu)  (22)
    T     = T' - Delta + correction

    with P~ = R - P, V~ = R' - V (16-17). q is advanced by the exact zero-order-hold discretisation of (20).
    Stability needs kappa >= M / mu + b tau / k for |D| <= M (23). With an ``output_limit`` the command
    is saturated and q is held while the command is at the limit (anti-windup).
    """

    #: steps elementwise on arrays with a leading batch axis (:mod:`contouring_ros.core.batch`)
    batchable = True

    def __init__(self, a, b, mu, kappa, gain, time_constant, sample_time, observer=None, output_limit=0.0):
        self.a, self.b, self.mu, self.kappa = float(a), float(b), float(mu), float(kappa)
        self.gain, self.time_constant = float(gain), float(time_constant)
        self.observer = observer
        self.output_limit = float(output_limit)
        self.q = 0.0
        self._q_decay = math.exp(-self.b * sample_time)
        self._q_input = (1.0 - self._q_decay) / self.b

    def step(self, ref_pos, ref_vel, ref_acc, position, velocity, correction) -> float:
        a, b, k, tau = self.a, self.b, self.gain, self.time_constant
        p_err = ref_pos - position
        v_err = ref_vel - velocity
        switch = self.mu * saturation((v_err + a * p_err + b * self.q) / self.mu)
        command = (((a + b) * tau - 1.0) / k) * v_err + (a * b * tau / k) * p_err \
            + _inverse_first_order(ref_vel, ref_acc, k, tau) + self.kappa * switch
        q = self.q
        self.q = self._q_decay * q + self._q_input * switch
        if self.observer is not None:
            command -= self.observer.update(velocity, ref_vel, ref_acc)
        command += correction
        if has_limit(self.output_limit):
            limited = symmetric_clip(command, self.output_limit)
            self.q = np.where(limited != command, q, self.q) if isinstance(limited, np.ndarray) \
                else (q if limited != command else self.q)        # q held while at the limit
            command = limited
        if self.observer is not None:
            self.observer.previous_command = command
        return command


class DirectServo:
    """No axis loop of its own: the command is the contour controller's output (clipped to
    ``output_limit``). For task-frame contour controllers that compute every axis' whole actuator
    command, such as :class:`contouring_ros.core.contouring.TaskFramePD` (paper 003 eq. 25)."""

    #: steps elementwise on arrays with a leading batch axis (:mod:`contouring_ros.core.batch`)
    batchable = True

    def __init__(self, output_limit: float = 0.0):
        self.output_limit = float(output_limit)

    def step(self, ref_pos, ref_vel, ref_acc, position, velocity, correction) -> float:
        if has_limit(self.output_limit):
            return symmetric_clip(correction, self.output_limit)
        return correction if isinstance(correction, np.ndarray) else float(correction)


def _zero_order_hold(a: np.ndarray, b: np.ndarray, sample_time: float) -> tuple:
    """Exact discretisation x+ = Phi x + Gamma w of x' = A x + B w with w held over the sample."""
    n, m = a.shape[0], b.shape[1]
    block = np.zeros((n + m, n + m))
    block[:n, :n], block[:n, n:] = a, b
    exponential = expm(block * sample_time)
    return exponential[:n, :n], exponential[:n, n:]


class ExtendedStateObserver:
    """Linear extended state observer of a mass-damper axis (paper 004 eq. 15-16).

    q^' = v^ + (alpha_1 / sigma) (q - q^)
    v^' = -(B / M) v^ + (K / M) u + d^ + (alpha_2 / sigma^2) (q - q^)
    d^' = (alpha_3 / sigma^3) (q - q^)

    estimates position, velocity and the lumped acceleration disturbance d of q'' = -(B/M) q' + (K/M) u + d
    from the measured position q and the command u. Eq. 16 as printed drops -(B/M) v^ (and writes q^ for
    v^ in its first line); the model term is kept here because the controller (eq. 24) compensates B/M v^
    itself, so d^ must be the disturbance alone. The error dynamics have the characteristic polynomial
    s^3 + alpha_1 s^2 + alpha_2 s + alpha_3 in sigma s (eq. 18-21). Discretised exactly, with u and q held
    over each sample.
    """

    #: steps elementwise on arrays with a leading batch axis (:mod:`contouring_ros.core.batch`)
    batchable = True

    def __init__(self, mass, damping, gain, alphas, sigma, sample_time, position=0.0, velocity=0.0):
        a1, a2, a3 = (float(a) for a in alphas)
        sigma = float(sigma)
        l1, l2, l3 = a1 / sigma, a2 / sigma**2, a3 / sigma**3
        a = np.array([[-l1, 1.0, 0.0], [-l2, -damping / mass, 1.0], [-l3, 0.0, 0.0]])
        b = np.array([[0.0, l1], [gain / mass, l2], [0.0, l3]])
        self._phi, self._gamma = _zero_order_hold(a, b, float(sample_time))
        self.state = np.array([float(position), float(velocity), 0.0])

    def update(self, command: float, position: float) -> None:
        """Advance over one sample with the command applied and the position measured at its start (a batch:
        commands and positions (B, 1), states (B, 3))."""
        if np.ndim(command) == 0:
            self.state = matvec(self._phi, self.state) + matvec(self._gamma, [command, position])
            return
        inputs = np.concatenate(np.broadcast_arrays(command, position), axis=-1)
        self.state = np.einsum("...ij,...j->...i", self._phi, self.state) \
            + np.einsum("...ij,...j->...i", self._gamma, inputs)

    def estimates(self) -> tuple:
        """(q^, v^, d^): floats, or (B, 1) columns for a batch."""
        if self.state.ndim == 2:
            return self.state[:, 0:1], self.state[:, 1:2], self.state[:, 2:3]
        return tuple(self.state)


class ESOSlidingModeServo:
    """Sliding mode position control on extended state observer estimates (paper 004 eq. 22-24).

    s = e' + c e with e = q - q_d (22), on the observer's estimates e^ = q^ - q_d, e^' = v^ - q_d':

    u = (K / M)^-1 (q_d'' + (B / M) v^ - c e^' - k s^ - d^)                                       (24)

    which makes s' = -k s when the estimates are exact. ``disturbance_compensation: false`` drops d^ from
    (24) (the paper's comparison "without ESO"): the observer still supplies q^ and v^. The observer is fed
    the command the actuator receives, the control plus the cross-coupled correction, so the correction is
    not mistaken for a disturbance and cancelled.
    """

    #: steps elementwise on arrays with a leading batch axis (:mod:`contouring_ros.core.batch`)
    batchable = True

    def __init__(self, mass, damping, gain, c, k, alphas, sigma, sample_time, position=0.0, velocity=0.0,
                 disturbance_compensation: bool = True, output_limit: float = 0.0):
        self.mass, self.damping, self.gain = float(mass), float(damping), float(gain)
        self.c, self.k = float(c), float(k)
        self.observer = ExtendedStateObserver(mass, damping, gain, alphas, sigma, sample_time, position, velocity)
        self.disturbance_compensation = bool(disturbance_compensation)
        self.output_limit = float(output_limit)

    def step(self, ref_pos, ref_vel, ref_acc, position, velocity, correction) -> float:
        q_hat, v_hat, d_hat = self.observer.estimates()
        error, error_rate = q_hat - ref_pos, v_hat - ref_vel
        surface = error_rate + self.c * error
        acceleration = ref_acc + self.damping / self.mass * v_hat - self.c * error_rate - self.k * surface
        if self.disturbance_compensation:
            acceleration -= d_hat
        command = self.mass / self.gain * acceleration + correction
        if has_limit(self.output_limit):
            command = symmetric_clip(command, self.output_limit)
        self.observer.update(command, position)
        return command


class PIDServo:
    """PID on the position error with the velocity error as its derivative, no feedforward (the PD baseline
    of paper 001 section 4 with ki = 0): T = kp (R - P) + ki int (R - P) + kd (R' - V) + correction."""

    #: steps elementwise on arrays with a leading batch axis (:mod:`contouring_ros.core.batch`)
    batchable = True

    def __init__(self, kp, ki, kd, sample_time, output_limit: float = 0.0):
        self.pid = DiscretePID(kp, ki, kd, sample_time)
        self.output_limit = float(output_limit)

    def step(self, ref_pos, ref_vel, ref_acc, position, velocity, correction) -> float:
        command = self.pid.step(ref_pos - position, ref_vel - velocity) + correction
        return self.pid.clamp(command, self.output_limit)


class CascadeServo:
    """P position loop over a PI velocity loop with Coulomb friction feedforward (paper 002, Fig. 5).

    V* = R' + kp_position (R - P) + correction                    (velocity command; the CCC acts here)
    T  = kp_velocity (V* - V) + ki_velocity int (V* - V) + F_c(V*)

    with F_c(V*) = coulomb_positive for V* > 0, -coulomb_negative for V* < 0 (in command units). For
    torque-driven axes (model mass_damper); the integral is held while the command is at ``output_limit``.
    """

    #: steps elementwise on arrays with a leading batch axis (:mod:`contouring_ros.core.batch`)
    batchable = True

    def __init__(self, kp_position, kp_velocity, ki_velocity, sample_time, coulomb_positive=0.0,
                 coulomb_negative=0.0, output_limit: float = 0.0):
        self.kp_position = float(kp_position)
        self.velocity_loop = DiscretePID(kp_velocity, ki_velocity, 0.0, sample_time)
        self.coulomb_positive, self.coulomb_negative = float(coulomb_positive), float(coulomb_negative)
        self.output_limit = float(output_limit)

    def step(self, ref_pos, ref_vel, ref_acc, position, velocity, correction) -> float:
        velocity_command = ref_vel + self.kp_position * (ref_pos - position) + correction
        command = self.velocity_loop.step(velocity_command - velocity, 0.0) \
            + coulomb_friction(velocity_command, self.coulomb_positive, self.coulomb_negative)
        return self.velocity_loop.clamp(command, self.output_limit)
