"""Interpolation: the curve-parameter schedule theta(t) and the reference it produces.

The reference at time t is R(theta(t)) with velocity R' theta_dot and acceleration
R'' theta_dot^2 + R' theta_ddot (chain rule on paper 000 eq. 3).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .curves import Curve

__all__ = ["UniformSchedule", "Reference", "reference"]


class UniformSchedule:
    """theta moves uniformly in time from ``theta_start`` to ``theta_end`` over ``duration``, then holds.

    Paper 000 section IV: theta = 2 a t / T - a for t in [0, T].
    """

    def __init__(self, theta_start: float, theta_end: float, duration: float):
        if duration <= 0.0:
            raise ValueError("schedule duration must be positive")
        self.theta_start = float(theta_start)
        self.theta_end = float(theta_end)
        self.duration = float(duration)
        self.rate = (self.theta_end - self.theta_start) / self.duration

    def __call__(self, t):
        """theta, theta_dot, theta_ddot at time(s) t."""
        t = np.asarray(t, dtype=float)
        moving = t < self.duration
        theta = np.where(moving, self.theta_start + self.rate * np.clip(t, 0.0, None), self.theta_end)
        theta_dot = np.where(moving, self.rate, 0.0)
        return theta, theta_dot, np.zeros_like(theta)


@dataclass(frozen=True)
class Reference:
    """Reference samples; arrays have a leading time axis when built for many times.

    Attributes
    ----------
    theta, theta_dot, theta_ddot : float or ndarray
        Curve parameter and its time derivatives.
    position, velocity, acceleration : ndarray, shape ([m,] n)
        Per-axis reference position [m], velocity [m/s] and acceleration [m/s^2].
    """

    theta: np.ndarray
    theta_dot: np.ndarray
    theta_ddot: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray


def reference(curve: Curve, schedule, t) -> Reference:
    """The reference of ``curve`` driven by ``schedule`` at time(s) ``t``."""
    theta, theta_dot, theta_ddot = schedule(t)
    d = curve.derivatives(theta, order=2)
    rate = np.asarray(theta_dot)[..., None]
    accel = np.asarray(theta_ddot)[..., None]
    return Reference(theta=theta, theta_dot=theta_dot, theta_ddot=theta_ddot, position=d[0],
                     velocity=d[1] * rate, acceleration=d[2] * rate * rate + d[1] * accel)
