"""Discrete PID used by the servo laws and the cross-coupled controllers."""
from __future__ import annotations

import numpy as np

from .plants import has_limit, symmetric_clip

__all__ = ["DiscretePID"]


class DiscretePID:
    """u_k = kp e_k + ki I_k + kd de_k, with I_k = I_{k-1} + Ts e_k (backward rectangle).

    The derivative is the measured error rate when the caller has one (a velocity error), otherwise the
    backward difference (e_k - e_{k-1}) / Ts, zero at the first step. Works elementwise on arrays, so
    one object can hold one PID per axis with the same gains (paper 000 eq. 15: G_i^c identical).

    Parameters
    ----------
    kp, ki, kd : float
        Proportional, integral [1/s] and derivative [s] gains of G(s) = kp + ki / s + kd s.
    sample_time : float
        Ts [s].
    """

    batchable = True

    def __init__(self, kp: float, ki: float, kd: float, sample_time: float):
        self.kp, self.ki, self.kd = float(kp), float(ki), float(kd)
        self.sample_time = float(sample_time)
        self.integral = 0.0
        self._previous = None
        self._increment = 0.0

    def step(self, error, error_rate=None):
        """Controller output for this step's ``error`` (scalar or array)."""
        self._increment = self.sample_time * error
        self.integral = self.integral + self._increment
        if error_rate is None:
            error_rate = (error - self._previous) / self.sample_time if self._previous is not None \
                else np.zeros_like(error)
        self._previous = error
        return self.kp * error + self.ki * self.integral + self.kd * error_rate

    def clamp(self, output, limit: float):
        """Saturate ``output`` to +-limit (limit 0: no limit) with anti-windup by conditional integration.

        Where the output saturates and this step's integration pushed it further out, that integration
        is taken back, so the integral does not wind up while the actuator is at its limit.
        """
        if not has_limit(limit):
            return output
        clipped = symmetric_clip(output, limit)
        pushing = (output != clipped) & (np.sign(self.ki * self._increment) == np.sign(output - clipped))
        self.integral = self.integral - np.where(pushing, self._increment, 0.0)
        return clipped if np.ndim(clipped) else float(clipped)
