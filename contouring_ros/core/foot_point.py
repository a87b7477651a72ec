"""The filtered Newton flow toward the foot point: :class:`~contouring_ros.core.estimators.NewtonEstimator`'s
inner iteration (paper 000 eq. 8-11), written once.

The estimator's pure path calls these functions with the curve itself as ``curve`` (``_formula`` gives its
columns); :mod:`contouring_ros.core.kernels` compiles copies of them whose ``_formula`` is the curve's formula
compiled and whose ``curve`` is the curve's parameters. The statements are IEEE double operations in one
order, so the copies give the pure path's numbers bit for bit.
"""
from __future__ import annotations

__all__ = ["foot_point_flow", "foot_point_flow_planar"]


def _formula(theta, curve):
    """The columns (R, R', ...) of ``curve`` at theta (in a compiled copy: the curve's compiled formula of
    its parameters)."""
    return curve.columns(theta)


def foot_point_flow_planar(curve, px, py, theta, filtered, decay, blend, gain, tolerance2, cap, lo, hi):
    """The filtered Newton flow (paper 000 eq. 8-11) on an open planar curve over the
    domain [lo, hi], for the position (px, py), from the estimate ``theta`` and the filter state
    ``filtered``: :func:`foot_point_flow` unrolled for two coordinates (the common case, which the pure path
    takes several times faster). Returns (theta, filtered, updates made, converged)."""
    n = 0
    converged = False
    while True:
        columns = _formula(theta, curve)
        rx, ry = columns[0]
        tx, ty = columns[1]
        gradient = (rx - px) * tx + (ry - py) * ty         # g = E^T R', eq. 9
        hessian = tx * tx + ty * ty                         # h ~= |R'|^2, eq. 11
        following = decay * filtered + blend * (gradient / hessian)
        new = theta - gain * following
        if lo > new:                      # clipped to the domain (a nan stays nan)
            new = lo
        if hi < new:
            new = hi
        moved = new - theta
        if ((gradient * gradient <= tolerance2 * hessian or (theta == lo and gradient > 0.0)
             or (theta == hi and gradient < 0.0)) and moved * moved * hessian <= tolerance2):
            converged = True
            break
        if n == cap:
            break
        theta, filtered = new, following
        n += 1
    return theta, filtered, n, converged


def foot_point_flow(curve, position, theta, filtered, decay, blend, gain, tolerance2, cap, lo, hi, closed):
    """The filtered Newton flow (paper 000 eq. 8-11) in any dimension, on an open or a
    closed curve (``closed``: theta wraps around the domain [lo, hi]), for ``position`` (a sequence of n
    floats), from the estimate ``theta`` and the filter state ``filtered``: at most ``cap`` updates
    theta <- theta - gain * following, following = decay * filtered + blend * g / h, until both the
    tangential residual g^2 <= tolerance2 h and the next update's length moved^2 h <= tolerance2 (the class
    docstring's stopping rule). Returns (theta, filtered, updates made, converged)."""
    n = 0
    converged = False
    while True:
        columns = _formula(theta, curve)
        point, tangent = columns[0], columns[1]
        gradient = 0.0
        hessian = 0.0
        for i in range(min(len(point), len(position))):
            gradient += (point[i] - position[i]) * tangent[i]      # g = E^T R', eq. 9
            hessian += tangent[i] * tangent[i]                     # h ~= |R'|^2, eq. 11
        following = decay * filtered + blend * (gradient / hessian)
        if closed:
            moved = -gain * following
            new = lo + (theta + moved - lo) % (hi - lo)
            at_end = False
        else:
            new = theta - gain * following
            if lo > new:
                new = lo
            if hi < new:
                new = hi
            moved = new - theta
            at_end = (theta == lo and gradient > 0.0) or (theta == hi and gradient < 0.0)
        if (gradient * gradient <= tolerance2 * hessian or at_end) and moved * moved * hessian <= tolerance2:
            converged = True
            break
        if n == cap:
            break
        theta, filtered = new, following
        n += 1
    return theta, filtered, n, converged
