"""Optional compiled kernels (numba) for the in-process simulation's innermost loops.

The filtered Newton flow of :class:`~contouring_ros.core.estimators.NewtonEstimator` iterates tens of times
per control step; on a parabola (paper 000's contour, the default experiment) each iteration is a handful of
multiplications and additions, and the Python or numpy overhead of an iteration is most of a run's time.
Where numba is installed (``pip install numba``; optional) the iteration on a :class:`~contouring_ros.core.
curves.Parabola` runs compiled, one member after another for a batch. Every operation is the pure path's,
in its order, on IEEE doubles (additions, multiplications, divisions, comparisons: no function whose last
bit could differ between implementations, and no contraction into fused multiply-adds), so the results are
the pure path's bit for bit (tests/core/test_kernels.py). Without numba, or with the environment variable
``CONTOURING_ROS_NUMBA=0``, the pure Python and numpy path runs.
"""
from __future__ import annotations

import os

import numpy as np

__all__ = ["ENABLED", "newton_parabola", "newton_parabola_batch"]

try:                                            # pragma: no cover - depends on the environment
    if os.environ.get("CONTOURING_ROS_NUMBA", "1") == "0":
        raise ImportError("disabled by CONTOURING_ROS_NUMBA=0")
    import numba
except ImportError:                             # the pure path
    numba = None

#: whether the compiled kernels are used
ENABLED = numba is not None


def _newton_parabola(h, lo, hi, px, py, theta, filtered, decay, blend, gain, tolerance2, cap):
    """The filtered Newton flow of NewtonEstimator._iterate on R = [t, h t^2] over [lo, hi] from (theta,
    filtered) for the position (px, py): (theta, filtered, updates made, converged)."""
    n = 0
    converged = False
    while True:
        tx = 1.0
        ty = 2.0 * h * theta
        gradient = (theta - px) * tx + (h * theta * theta - py) * ty        # g = E^T R', eq. 9
        hessian = tx * tx + ty * ty                                       # h ~= |R'|^2, eq. 11
        following = decay * filtered + blend * (gradient / hessian)
        new = theta - gain * following
        if lo > new:                      # min(max(new, lo), hi) as Python's builtins take it (a nan stays)
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


def _newton_parabola_batch(h, lo, hi, px, py, theta, filtered, decay, blend, gain, tolerance2, cap, active,
                           iterations, capped):
    """:func:`_newton_parabola` for each active member j of a batch (every argument an array (B,), ``theta``,
    ``filtered`` updated in place, ``iterations`` and ``capped`` written); inactive members are left as they
    are with 0 updates."""
    for j in range(theta.shape[0]):
        if not active[j]:
            iterations[j] = 0
            capped[j] = False
            continue
        t, f, n, done = _newton_parabola(h[j], lo[j], hi[j], px[j], py[j], theta[j], filtered[j], decay[j], blend[j],
                                         gain[j], tolerance2[j], cap[j])
        theta[j], filtered[j], iterations[j], capped[j] = t, f, n, not done


if numba is not None:                            # pragma: no cover - depends on the environment
    # error_model="numpy": a division by zero gives inf or nan as numpy's does, not an exception; no fastmath
    _newton_parabola = numba.njit(cache=True, error_model="numpy")(_newton_parabola)
    _newton_parabola_batch = numba.njit(cache=True, error_model="numpy")(_newton_parabola_batch)


def newton_parabola(h, lo, hi, px, py, theta, filtered, decay, blend, gain, tolerance2, cap):
    """The compiled flow of one position (floats; ``cap`` int): (theta, filtered, updates, converged), or None
    without numba."""
    if numba is None:
        return None
    return _newton_parabola(h, lo, hi, px, py, theta, filtered, decay, blend, gain, tolerance2, cap)


def newton_parabola_batch(h, lo, hi, position, theta, filtered, decay, blend, gain, tolerance2, cap, active):
    """The compiled flow of a batch: positions (B, 2), every other per-member value a float or an array of
    shape (B, 1). Returns (theta, filtered, iterations, capped), each (B, 1), as
    ``NewtonEstimator._iterate_batch`` leaves them, or None without numba."""
    if numba is None:
        return None
    b = position.shape[0]

    def column(value, dtype=float):
        return np.ascontiguousarray(np.broadcast_to(value, (b, 1))[:, 0], dtype=dtype)
    theta, filtered = column(theta).copy(), column(filtered).copy()
    iterations, capped = np.zeros(b, dtype=np.int64), np.zeros(b, dtype=np.bool_)
    _newton_parabola_batch(column(h), column(lo), column(hi), column(position[:, 0:1]), column(position[:, 1:2]), theta,
                           filtered, column(decay), column(blend), column(gain), column(tolerance2),
                           column(cap, np.int64), column(active, np.bool_), iterations, capped)
    return theta[:, None], filtered[:, None], iterations[:, None].astype(int), capped[:, None]
