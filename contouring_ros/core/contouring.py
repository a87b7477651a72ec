"""Cross-coupled contour controllers: a contour error estimate in, one correction per axis out.

The corrections add to the axes' actuator commands (see :mod:`contouring_ros.core.servo`).
"""
from __future__ import annotations

import numpy as np

from .curves import Curve
from .geometry import left_normal, unit_tangent
from .pid import DiscretePID

__all__ = ["NoCoupling", "VariableGainCCC", "UnitVectorCCC"]


class NoCoupling:
    """No cross-coupling: zero corrections (the uncoupled baseline)."""

    def __init__(self, n_axes: int):
        self.n_axes = int(n_axes)

    def step(self, estimate) -> np.ndarray:
        return np.zeros(self.n_axes)


class VariableGainCCC:
    """Koren & Lo variable-gain cross-coupled controller (paper 000 Fig. 5 right; Koren & Lo 1991).

    The scalar contour error epsilon drives one PID G_c(s) = kp + ki/s + kd s, and its output is
    distributed to the axes with the time-varying gains C = n, the unit normal along which the estimate
    measures the error (C = E / epsilon; the contour normal at the estimated foot point while epsilon = 0):
    u = C G_c(epsilon). For the tangent-line estimate epsilon = C_y E_y - C_x E_x with C_x = sin(phi),
    C_y = cos(phi), phi the tangent angle at the reference point: Koren & Lo's gains for linear contours.
    Planar contours only.
    """

    def __init__(self, curve: Curve, kp: float, ki: float, kd: float, sample_time: float,
                 output_limit: float = 0.0):
        if curve.dimension != 2:
            raise ValueError("the variable-gain CCC is defined for planar (2-axis) contours")
        self.curve = curve
        self.pid = DiscretePID(kp, ki, kd, sample_time)
        self.output_limit = float(output_limit)

    def step(self, estimate) -> np.ndarray:
        if abs(estimate.signed) > 1e-12:
            gains = np.asarray(estimate.vector, dtype=float) / estimate.signed
        else:
            gains = left_normal(unit_tangent(self.curve, estimate.theta))
        return gains * self.pid.clamp(self.pid.step(estimate.signed), self.output_limit)


class UnitVectorCCC:
    """Unit-vector cross-coupled controller with one PID per axis (paper 000 eq. 15).

    The contour error vector E* = |E*| epsilon, epsilon the unit contour error vector, is resolved along
    the axes and each component E*_i drives its own PID G_i^c(s) = kp + ki/s + kd s; thanks to the
    normalisation all axes share the same gains. u_i = G_i^c(E*_i). An ``output_limit`` saturates each
    correction, with anti-windup (see :meth:`DiscretePID.clamp`); the variable-gain CCC limits G_c's output.
    """

    def __init__(self, n_axes: int, kp: float, ki: float, kd: float, sample_time: float,
                 output_limit: float = 0.0):
        self.n_axes = int(n_axes)
        self.pid = DiscretePID(kp, ki, kd, sample_time)
        self.output_limit = float(output_limit)

    def step(self, estimate) -> np.ndarray:
        output = self.pid.step(np.asarray(estimate.vector, dtype=float))
        return np.asarray(self.pid.clamp(output, self.output_limit), dtype=float)
