"""Per-axis position servo laws.

Every law has the same step: the axis reference (position, velocity, acceleration), the axis state
(position, velocity) and the cross-coupled correction at step k give the actuator command at k. The
correction adds to the command (Koren's cross-coupling structure; paper 000 Fig. 5).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .geometry import matvec_rows, sum_of_products
from .pid import DiscretePID
from .plants import coulomb_friction, first_order_hold_terms, has_limit, symmetric_clip

__all__ = ["PIDFeedforwardServo", "IntegralSlidingModeServo", "DisturbanceObserver", "DirectServo",
           "ExtendedStateObserver", "ESOSlidingModeServo", "PIDServo", "CascadeServo", "ZPETCServo",
           "ZPETCDesign", "closed_loop", "zpetc_design", "saturation"]


def saturation(u: float) -> float:
    """sat(u) = u for |u| <= 1, sign(u) otherwise (paper 000, after eq. 20); elementwise on arrays."""
    return np.minimum(np.maximum(u, -1.0), 1.0) if isinstance(u, np.ndarray) else max(-1.0, min(1.0, u))


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
    #: every number of its own elementwise too: a batch steps the axes of a member as rows of one object
    batch_axes = True

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
    #: every number of its own elementwise too: a batch steps the axes of a member as rows of one object
    batch_axes = True

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
    #: every number of its own elementwise too: a batch steps the axes of a member as rows of one object
    batch_axes = True

    def __init__(self, output_limit: float = 0.0):
        self.output_limit = float(output_limit)

    def step(self, ref_pos, ref_vel, ref_acc, position, velocity, correction) -> float:
        if has_limit(self.output_limit):
            return symmetric_clip(correction, self.output_limit)
        return correction if isinstance(correction, np.ndarray) else float(correction)


def _zero_order_hold(a: np.ndarray, b: np.ndarray, sample_time: float) -> tuple:
    """Exact discretisation x+ = Phi x + Gamma w of x' = A x + B w with w held over the sample."""
    from scipy.linalg import expm     # here, not at the top: scipy.linalg takes a node 0.3 s to import
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
        self._rows = None          # _phi and _gamma as lists of rows of floats, for one run's steps

    def update(self, command: float, position: float) -> None:
        """Advance over one sample with the command applied and the position measured at its start (a batch:
        commands and positions (B, 1), states (B, 3))."""
        if command.__class__ is float or np.ndim(command) == 0:
            # Phi x + Gamma [u, q], each row's products summed left to right (geometry.matvec), on floats
            if self._rows is None:
                self._rows = (self._phi.tolist(), self._gamma.tolist())
            state, inputs = self.state.tolist(), [float(command), float(position)]
            self.state = np.array([sum_of_products(phi, state) + sum_of_products(gamma, inputs)
                                   for phi, gamma in zip(*self._rows)])
            return
        # the same sums in the same order, member by member (geometry.matvec_rows), so that a member of a
        # batch has the numbers of its run alone
        inputs = np.concatenate(np.broadcast_arrays(command, position), axis=-1)
        self.state = matvec_rows(self._phi, self.state) + matvec_rows(self._gamma, inputs)

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
    #: every number of its own elementwise too: a batch steps the axes of a member as rows of one object
    batch_axes = True

    def __init__(self, mass, damping, gain, c, k, alphas, sigma, sample_time, position=0.0, velocity=0.0,
                 disturbance_compensation: bool = True, output_limit: float = 0.0):
        self.mass, self.damping, self.gain = float(mass), float(damping), float(gain)
        self.c, self.k = float(c), float(k)
        self.observer = ExtendedStateObserver(mass, damping, gain, alphas, sigma, sample_time, position, velocity)
        # d^'s weight in (24), 1 or 0: a number, so that runs with and without it share a batch
        self.compensation = 1.0 if disturbance_compensation else 0.0
        self.output_limit = float(output_limit)

    def step(self, ref_pos, ref_vel, ref_acc, position, velocity, correction) -> float:
        q_hat, v_hat, d_hat = self.observer.estimates()
        error, error_rate = q_hat - ref_pos, v_hat - ref_vel
        surface = error_rate + self.c * error
        acceleration = ref_acc + self.damping / self.mass * v_hat - self.c * error_rate - self.k * surface
        acceleration = acceleration - self.compensation * d_hat
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
    #: every number of its own elementwise too: a batch steps the axes of a member as rows of one object
    batch_axes = True

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
    #: every number of its own elementwise too: a batch steps the axes of a member as rows of one object
    batch_axes = True

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


# --------------------------------------------------------------------------------------------------- ZPETC


@dataclass(frozen=True)
class ZPETCDesign:
    """A zero phase error tracking controller for one axis' closed loop (Tomizuka 1987, DOI 10.1115/1.3143822;
    the equations below in the paper's notation, unnumbered here).

    The closed loop from the loop's reference r to the position y is

        G_c(z^-1) = z^-d B_a(z^-1) B_u(z^-1) / A(z^-1)                                      (closed loop)

    where B_u holds the zeros that cannot be cancelled (outside the unit circle, or on the negative real side
    of it near -1, where their inverse rings from sample to sample) and B_a the others. The feedforward

        r(k) = A(z^-1) B_u*(z^-1) / (B_a(z^-1) B_u(1)^2) y_d(k + d + s)                    (ZPETC)

    with B_u*(z^-1) = b_us + b_u(s-1) z^-1 + ... + b_u0 z^-s (B_u's coefficients reversed, s its degree)
    gives y(k) = B_u(z) B_u(z^-1) / B_u(1)^2 y_d(k) (the tracking result): zero phase at every frequency and unit gain at
    steady state, using the desired position d + s steps ahead.

    Attributes
    ----------
    numerator, denominator : ndarray
        G_c's B = B_a B_u and A, coefficients of z^-1 from z^0 (A(0) = 1); the delay d aside.
    delay : int
        d, the closed loop's delay in samples.
    uncancelled : ndarray
        B_u's zeros.
    feedforward : ndarray
        A B_u* / (B_u(1)^2 b_a0): the coefficients of y_d(k + d + s - j), j = 0, 1, ...
    recursion : ndarray
        B_a / b_a0 without its leading 1: r(k) = sum feedforward_j y_d(k+d+s-j) - sum recursion_i r(k-1-i).
    """

    numerator: np.ndarray
    denominator: np.ndarray
    delay: int
    uncancelled: np.ndarray
    feedforward: np.ndarray
    recursion: np.ndarray

    @property
    def preview(self) -> int:
        """d + s: how many steps ahead the feedforward reads the desired position."""
        return self.delay + len(self.uncancelled)


def closed_loop(kp, ki, kd, gain, time_constant, sample_time, command_delay: int = 0) -> tuple:
    """(B, A, d) of the position loop of :class:`ZPETCServo` on the first-order velocity axis (paper 000 eq. 2,
    K / (s (tau s + 1)) from command to position; a mass-damper K / (M s^2 + B s) is K/B, M/B): the
    axis discretised exactly under a zero-order hold, ``command_delay`` samples of computation delay, and

        u(k) = kp e(k) + ki I(k) - kd V(k),  e = r - y,  I(k) = I(k-1) + Ts e(k).

    With C(z) = kp + ki Ts z / (z - 1) = N_c / D_c and the axis' P/U = N_p / D_p, V/U = k (1 - alpha) / (z - alpha):

        Y / R = N_c N_p / (z^D D_c D_p + N_c N_p + kd k (1 - alpha) (z - 1) D_c)

    returned as G_c = z^-d B(z^-1) / A(z^-1), A(0) = 1."""
    ts = float(sample_time)
    alpha, pv, vu, pu = first_order_hold_terms(float(gain), float(time_constant), ts)
    n_p, d_p = np.array([pu, pv * vu - alpha * pu]), np.polymul([1.0, -1.0], [1.0, -alpha])
    if ki:
        n_c, d_c = np.array([kp + ki * ts, -kp]), np.array([1.0, -1.0])
    else:            # no integral: the (z - 1) of C's denominator and numerator would cancel
        n_c, d_c = np.array([float(kp)]), np.array([1.0])
    numerator = np.polymul(n_c, n_p)
    shifted = np.polymul(np.concatenate([[1.0], np.zeros(int(command_delay))]), np.polymul(d_c, d_p))
    denominator = np.polyadd(np.polyadd(shifted, numerator), kd * vu * np.polymul([1.0, -1.0], d_c))
    lead = denominator[0]
    return numerator / lead, denominator / lead, len(denominator) - len(numerator)


def zpetc_design(numerator, denominator, delay: int, zero_radius: float = 0.5) -> ZPETCDesign:
    """The ZPETC of G_c = z^-d B(z^-1) / A(z^-1) (:class:`ZPETCDesign`). A zero z_i of B is not cancelled
    when |z_i| >= 1, or when Re z_i < 0 and |z_i| >= ``zero_radius`` (Tomizuka 1987: 'unacceptable' zeros;
    a sampled axis has one near -1)."""
    numerator, denominator = np.asarray(numerator, dtype=float), np.asarray(denominator, dtype=float)
    zeros = np.roots(numerator)
    bad = (np.abs(zeros) >= 1.0) | ((zeros.real < 0.0) & (np.abs(zeros) >= zero_radius))
    b_u = np.real(np.poly(zeros[bad])) if bad.any() else np.array([1.0])
    b_a = numerator[0] * (np.real(np.poly(zeros[~bad])) if (~bad).any() else np.array([1.0]))
    feedforward = np.polymul(denominator, b_u[::-1]) / (np.sum(b_u) ** 2 * b_a[0])
    return ZPETCDesign(numerator=numerator, denominator=denominator, delay=int(delay), uncancelled=zeros[bad],
                       feedforward=feedforward, recursion=b_a[1:] / b_a[0])


def _steady_past(taps, recursion, preview: int) -> np.ndarray:
    """(2, 3) W: the filter's steady output r(k - i) = sum_m W[i-1, m] c_m, i = 1, 2, for the desired motion
    y_d(k + j) = c0 + c1 j + c2 j^2 (a quadratic in the steps j from now). The recursion
    r(j) + sum_i recursion_i r(j - 1 - i) = sum_p taps_p y_d(j + p - (L - 1 - preview)) maps a quadratic to a
    quadratic r(j) = e0 + e1 j + e2 j^2 (B_a(1) != 0); matching it at j = 0, 1, 2 gives e for each c_m."""
    taps, recursion = np.asarray(taps, dtype=float), np.asarray(recursion, dtype=float)
    offsets = np.arange(len(taps)) - (len(taps) - 1 - preview)
    lags = np.arange(len(recursion) + 1)
    weights = np.concatenate([[1.0], recursion])
    at = np.arange(3.0)
    lhs = np.array([[np.sum(weights * (j - lags) ** m) for m in range(3)] for j in at])
    rhs = np.array([[np.sum(taps * (j + offsets) ** m) for m in range(3)] for j in at])
    e = np.linalg.solve(lhs, rhs)          # column m: r's coefficients for y_d = j^m
    return np.array([[np.sum(e[:, m] * (-i) ** np.arange(3)) for m in range(3)] for i in (1, 2)])


class ZPETCServo:
    """PID position loop with a zero phase error tracking feedforward (Tomizuka, "Zero phase error tracking
    algorithm for digital control", ASME J. Dyn. Syst. Meas. Control 109, 1987).

    The loop u = kp e + ki I - kd V + correction (e = r - y, derivative on the measured velocity) follows r,
    which the ZPETC (:func:`zpetc_design`) makes from the desired position y_d up to
    :attr:`preview` steps ahead: the interpolator's reference at k and the preview it publishes with it
    (:meth:`look_ahead`; docs/ARCHITECTURE.md, "Reference preview"). The design uses the axis model (gain,
    time constant) and the computation delay the servo is given, so a plant that differs from the model
    leaves a tracking error the feedback takes up.

    Every coefficient sits in a window of fixed length over y_d(k + P - L + 1 .. k + P), P = command_delay + 3
    (the most d + s can be) and the recursion on two past r, padded with zeros: servos of one structure
    share their shapes whatever their gains, and step as one batch (core/batch.py).
    """

    batchable = True
    batch_shared = ("preview",)

    def __init__(self, kp, ki, kd, gain, time_constant, sample_time, command_delay: int = 0,
                 zero_radius: float = 0.5, output_limit: float = 0.0):
        self.pid = DiscretePID(kp, ki, kd, sample_time)
        self.output_limit = float(output_limit)
        numerator, denominator, delay = closed_loop(kp, ki, kd, gain, time_constant, sample_time, command_delay)
        design = zpetc_design(numerator, denominator, delay, zero_radius)
        self.preview = int(command_delay) + 3
        length = int(command_delay) + 6            # the oldest y_d any design reads: k + d + s - (n + s)
        taps = np.zeros(length)
        first = self.preview - design.preview        # y_d(k + d + s) sits this many places before the newest
        taps[length - 1 - first - np.arange(len(design.feedforward))] = design.feedforward
        self.taps = tuple(float(c) for c in taps)    # oldest first, as the window
        recursion = np.zeros(2)
        recursion[:len(design.recursion)] = design.recursion
        self.recursion = tuple(float(c) for c in recursion)
        self.sample_time = float(sample_time)
        self.gain, self.time_constant = float(gain), float(time_constant)
        self.command_delay = int(command_delay)
        self.start_weights = tuple(float(w) for w in _steady_past(taps, recursion, self.preview).ravel())
        self.window = ()            # y_d, oldest first, ending at k + preview; filled at the first step
        self.past = ()              # r(k-1), r(k-2)
        self.ahead = ()

    def look_ahead(self, positions) -> None:
        """This step's desired positions at k + 1 .. k + :attr:`preview` (floats, or (B, 1) columns)."""
        self.ahead = tuple(positions)

    def _start(self, ref_pos, ref_vel, ref_acc) -> tuple:
        """At the first step the past is the motion the axis starts in: y_d before k extrapolated from the
        reference's position, velocity and acceleration, and r(k-1), r(k-2) the filter's steady output for
        that motion (:func:`_steady_past`): an axis that starts moving on its reference gets no transient
        from a past held still (which the filter's 1 / b_a0 ~ 1 / (k Ts^2) gain would turn into a jolt).
        Returns the motion's (c0, c1, c2)."""
        ts = self.sample_time
        motion = (ref_pos, ref_vel * ts, 0.5 * ref_acc * ts * ts)   # y_d(k + j) = c0 + c1 j + c2 j^2
        older = len(self.taps) - self.preview - 1
        self.window = tuple(motion[0] - motion[1] * j + motion[2] * (j * j) for j in range(older, 0, -1)) \
            + (ref_pos,) + self.ahead
        w = self.start_weights
        self.past = (w[0] * motion[0] + w[1] * motion[1] + w[2] * motion[2],
                     w[3] * motion[0] + w[4] * motion[1] + w[5] * motion[2])
        return motion

    def _start_integral(self, motion, error, velocity) -> None:
        """Bumpless start: the integral that makes the first command the one the sampled axis model needs to
        move on the starting motion y(j) = c0 + c1 j + c2 j^2 (:meth:`_start`): with the axis' P/U = N_p / D_p
        (:func:`closed_loop`), pu u(j+1) + q u(j) = y(j+2) - (1 + alpha) y(j+1) + alpha y(j) has the
        solution u(j) = u0 + u1 j, and the command computed now acts after ``command_delay`` steps
        (no integral: nothing to set; in a batch, the members with one)."""
        pid = self.pid
        if np.any(pid.ki):
            alpha, pv, vu, pu = first_order_hold_terms(self.gain, self.time_constant, self.sample_time)
            q = pv * vu - alpha * pu
            c0, c1, c2 = motion
            delay = self.command_delay

            def moved(j):                   # y(j+2) - (1 + alpha) y(j+1) + alpha y(j); c0 cancels
                return (1.0 - alpha) * c1 + c2 * ((j + 2) ** 2 - (1.0 + alpha) * (j + 1) ** 2 + alpha * j * j)
            first, second = moved(0), moved(1)
            u1 = (second - first) / (pu + q)
            wanted = (first - pu * u1) / (pu + q) + u1 * delay
            if np.ndim(pid.ki) == 0:
                pid.integral = (wanted - pid.kp * error + pid.kd * velocity) / pid.ki - pid.sample_time * error
            else:
                with np.errstate(divide="ignore", invalid="ignore"):
                    start = (wanted - pid.kp * error + pid.kd * velocity) / pid.ki - pid.sample_time * error
                pid.integral = np.where(pid.ki != 0, start, pid.integral)

    def step(self, ref_pos, ref_vel, ref_acc, position, velocity, correction) -> float:
        motion = self._start(ref_pos, ref_vel, ref_acc) if not self.window else None
        if motion is None:
            self.window = self.window[1:] + self.ahead[-1:]
        loop_reference = self.taps[0] * self.window[0]
        for tap, value in zip(self.taps[1:], self.window[1:]):
            loop_reference = loop_reference + tap * value
        loop_reference = loop_reference - self.recursion[0] * self.past[0] - self.recursion[1] * self.past[1]
        self.past = (loop_reference, self.past[0])
        if motion is not None:
            self._start_integral(motion, loop_reference - position, velocity)
        command = self.pid.step(loop_reference - position, -velocity) + correction
        return self.pid.clamp(command, self.output_limit)
