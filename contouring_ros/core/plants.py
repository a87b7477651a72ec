"""Axis dynamics, discretised exactly under a zero-order-hold input.

Each plant holds its state (position, velocity), applies a command over one sample period
[t_k, t_k+1) and returns the state at k+1.
"""
from __future__ import annotations

import math

import numpy as np

from .disturbances import NoDisturbance

__all__ = ["FirstOrderVelocityAxis", "MassDamperAxis", "coulomb_friction", "quantize", "has_limit", "symmetric_clip"]


def quantize(value: float, resolution: float) -> float:
    """``value`` rounded to the nearest multiple of ``resolution`` (0: unchanged), as an encoder reads it."""
    if not resolution:
        return value
    if np.ndim(value) or np.ndim(resolution):          # a batch (both round half to even)
        return np.round(value / resolution) * resolution
    return round(value / resolution) * resolution


class Axis:
    """What every axis model shares: its measurement. ``measure()`` gives the (position, velocity) the
    drive reports: the position read by an encoder of ``encoder_resolution`` [m] (0: exact), the velocity
    as the drive's own estimate (taken exact)."""

    encoder_resolution = 0.0
    position = 0.0
    velocity = 0.0

    def measure(self) -> tuple[float, float]:
        return quantize(self.position, self.encoder_resolution), self.velocity


class FirstOrderVelocityAxis(Axis):
    """First-order velocity axis of paper 000 eq. 1-2.

    dP/dt = V,  dV/dt = -V / tau + (k / tau) (T + D)

    with command T and disturbance D held constant over each sample period. The step is the exact
    zero-order-hold discretisation (no Euler error): with alpha = exp(-Ts / tau) and u = T + D,

    V+ = alpha V + k (1 - alpha) u
    P+ = P + tau (1 - alpha) V + k (Ts - tau (1 - alpha)) u

    Parameters
    ----------
    gain : float
        DC gain k [m/s per command unit].
    time_constant : float
        tau [s].
    sample_time : float
        Ts [s].
    disturbance : callable t -> float, optional
        D(t) in command units.
    position, velocity : float
        Initial state [m], [m/s].
    saturation : float
        Actuator limit: the command is clipped to +-saturation before the disturbance adds (0: none).
    """

    #: steps elementwise on arrays with a leading batch axis (:mod:`contouring_ros.core.batch`)
    batchable = True

    def __init__(self, gain: float, time_constant: float, sample_time: float, disturbance=None,
                 position: float = 0.0, velocity: float = 0.0, saturation: float = 0.0,
                 encoder_resolution: float = 0.0):
        if gain <= 0.0 or time_constant <= 0.0 or sample_time <= 0.0:
            raise ValueError("gain, time constant and sample time must be positive")
        self.gain = float(gain)
        self.time_constant = float(time_constant)
        self.sample_time = float(sample_time)
        self.disturbance = disturbance or NoDisturbance()
        alpha = math.exp(-self.sample_time / self.time_constant)
        self._alpha = alpha
        self._pv = self.time_constant * (1.0 - alpha)
        self._vu = self.gain * (1.0 - alpha)
        self._pu = self.gain * (self.sample_time - self._pv)
        self.position = float(position)
        self.velocity = float(velocity)
        self.saturation = float(saturation)
        self.encoder_resolution = float(encoder_resolution)

    def step(self, command: float, t: float) -> tuple[float, float]:
        """Apply ``command`` over [t, t + Ts) and return the (position, velocity) at t + Ts."""
        if has_limit(self.saturation):
            command = symmetric_clip(command, self.saturation)
        u = command + self.disturbance(t)
        p, v = self.position, self.velocity
        self.position = p + self._pv * v + self._pu * u
        self.velocity = self._alpha * v + self._vu * u
        return self.position, self.velocity


def has_limit(limit) -> bool:
    """Whether a limit (0: none) limits anything; a batch of limits does when any of them is set."""
    return limit != 0.0 if limit.__class__ is float else bool(np.any(limit))


def symmetric_clip(value, limit):
    """``value`` clipped to +-``limit``; elementwise for arrays, where a limit of 0 means no limit."""
    if isinstance(value, np.ndarray) or isinstance(limit, np.ndarray):
        limit = np.where(np.asarray(limit) > 0.0, limit, np.inf)
        return np.clip(value, -limit, limit)
    return max(-limit, min(limit, value))


def coulomb_friction(velocity: float, positive: float, negative: float) -> float:
    """Coulomb friction in command units: ``positive`` while moving forward, -``negative`` backward, 0 at rest
    (elementwise for arrays)."""
    if isinstance(velocity, np.ndarray):
        return np.where(velocity > 0.0, positive, np.where(velocity < 0.0, -np.asarray(negative), 0.0))
    if velocity > 0.0:
        return positive
    if velocity < 0.0:
        return -negative
    return 0.0


class MassDamperAxis(Axis):
    """Mass-damper feed drive with Coulomb friction and actuator saturation (papers 001 eq. 1, 003 eq. 18,
    004 eq. 12).

    M d2P/dt2 + B dP/dt = K (sat(T) + D - F_c(dP/dt))

    or, with ``disturbance_unit: acceleration``, M d2P/dt2 + B dP/dt = K (sat(T) - F_c) + M D: the
    disturbance D added to the acceleration, as in paper 004 eq. 13-14 (q'' = -(B/M) q' + (K_f/M) u + d).
    The transfer function from command to position is K / (M s^2 + B s) (paper 003's helix axes
    1/(s^2 + 200 s) are M = 1, B = 200, K = 1; its XY stage 16.23/(s^2 + 798.5 s) is M = 1, B = 798.5,
    K = 16.23). The command T is clipped to +-saturation, the disturbance D and the friction F_c (both in
    command units, like the paper's volts) add to it.

    Discretisation: exact zero-order hold of the linear part. With a = B / M, e = exp(-a Ts) and the
    held acceleration input w = K u / M,

    V+ = e V + (1 - e) / a w
    P+ = P + (1 - e) / a V + (Ts - (1 - e) / a) / a w          (a = 0: V+ = V + Ts w, P+ = P + Ts V + Ts^2 w / 2)

    The Coulomb friction is sampled with the velocity at the start of each step and held over it: exact
    while the axis does not reverse within a step, accurate to one sample at reversals (stick-slip is not
    modelled).
    """

    #: steps elementwise on arrays with a leading batch axis (:mod:`contouring_ros.core.batch`)
    batchable = True

    def __init__(self, mass: float, damping: float, gain: float, sample_time: float, disturbance=None,
                 position: float = 0.0, velocity: float = 0.0, saturation: float = 0.0,
                 coulomb_positive: float = 0.0, coulomb_negative: float = 0.0,
                 disturbance_unit: str = "command", encoder_resolution: float = 0.0):
        if mass <= 0.0 or gain <= 0.0 or sample_time <= 0.0 or damping < 0.0:
            raise ValueError("mass, gain and sample time must be positive and damping non-negative")
        self.mass, self.damping, self.gain = float(mass), float(damping), float(gain)
        self.sample_time = ts = float(sample_time)
        self.disturbance = disturbance or NoDisturbance()
        self.saturation = float(saturation)
        self.coulomb_positive, self.coulomb_negative = float(coulomb_positive), float(coulomb_negative)
        a = self.damping / self.mass
        if a * ts < 1e-9:
            self._vv, self._vw, self._pv, self._pw = 1.0, ts, ts, 0.5 * ts * ts
        else:
            one_minus_e = -math.expm1(-a * ts)
            self._vv, self._vw = 1.0 - one_minus_e, one_minus_e / a
            self._pv, self._pw = one_minus_e / a, (ts - one_minus_e / a) / a
        self._input_scale = self.gain / self.mass
        if disturbance_unit not in ("command", "acceleration"):
            raise ValueError(f"disturbance_unit must be command or acceleration, got {disturbance_unit!r}")
        self._disturbance_scale = 1.0 if disturbance_unit == "command" else self.mass / self.gain
        self.encoder_resolution = float(encoder_resolution)
        self.position = float(position)
        self.velocity = float(velocity)

    def step(self, command: float, t: float) -> tuple[float, float]:
        """Apply ``command`` over [t, t + Ts) and return the (position, velocity) at t + Ts."""
        if has_limit(self.saturation):
            command = symmetric_clip(command, self.saturation)
        p, v = self.position, self.velocity
        w = self._input_scale * (command + self._disturbance_scale * self.disturbance(t)
                                 - coulomb_friction(v, self.coulomb_positive, self.coulomb_negative))
        self.position = p + self._pv * v + self._pw * w
        self.velocity = self._vv * v + self._vw * w
        return self.position, self.velocity
