"""Axis dynamics, discretised exactly under a zero-order-hold input.

Each plant holds its state (position, velocity), applies a command over one sample period
[t_k, t_k+1) and returns the state at k+1.
"""
from __future__ import annotations

import math

from .disturbances import NoDisturbance

__all__ = ["FirstOrderVelocityAxis"]


class FirstOrderVelocityAxis:
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

    def __init__(self, gain: float, time_constant: float, sample_time: float, disturbance=None,
                 position: float = 0.0, velocity: float = 0.0, saturation: float = 0.0):
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

    def step(self, command: float, t: float) -> tuple[float, float]:
        """Apply ``command`` over [t, t + Ts) and return the (position, velocity) at t + Ts."""
        if self.saturation:
            command = max(-self.saturation, min(self.saturation, command))
        u = command + self.disturbance(t)
        p, v = self.position, self.velocity
        self.position = p + self._pv * v + self._pu * u
        self.velocity = self._alpha * v + self._vu * u
        return self.position, self.velocity
