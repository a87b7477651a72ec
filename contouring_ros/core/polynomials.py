"""Polynomials in z and rationals of them: the arithmetic the linear loops of :mod:`contouring_ros.core.margins`
are built with.

A polynomial is a 1-D array of its coefficients in numpy order, highest power first; a rational is a pair
(num, den) of them. Sums and products cancel the common factors z and (z - 1), the only poles the controllers
and the plants share with a numerator (integrators, backward differences, delays).
"""
from __future__ import annotations

import numpy as np

__all__ = ["trim", "polymul", "cancel", "rational_sum", "rational_product", "ZERO", "CANCEL_TOLERANCE"]

CANCEL_TOLERANCE = 1e-10      # relative size of a polynomial's value at z = 0 or 1 that counts as a root there


def trim(p) -> np.ndarray:
    """``p`` as a float array without its leading zeros (the zero polynomial: [0])."""
    p = np.atleast_1d(np.asarray(p, dtype=float))
    nonzero = np.flatnonzero(p)
    return p[nonzero[0]:] if nonzero.size else np.zeros(1)


def polymul(a, b) -> np.ndarray:
    """a(z) b(z): numpy's polymul without its poly1d round trip (the same coefficients, leading zeros kept:
    :func:`trim` drops them). A search asks for a loop's robustness at every point."""
    return np.convolve(np.atleast_1d(np.asarray(a, dtype=float)), np.atleast_1d(np.asarray(b, dtype=float)))


def _has_root(p: np.ndarray, z: float) -> bool:
    if len(p) < 2:
        return False
    scale = float(np.sum(np.abs(p)))
    return abs(float(np.polyval(p, z))) <= CANCEL_TOLERANCE * scale


def _deflate(p: np.ndarray, z: float) -> np.ndarray:
    """p(x) / (x - z) for a root z of p (the remainder, ~0, dropped)."""
    return np.polydiv(p, np.array([1.0, -z]))[0]


def cancel(num, den) -> tuple:
    """num / den with the common factors z and (z - 1) removed: the only poles the controllers and the
    plants share with a numerator (integrators, backward differences, delays)."""
    num, den = trim(num), trim(den)
    changed = True
    while changed and len(num) > 1 and len(den) > 1:
        changed = False
        for root in (0.0, 1.0):
            if _has_root(num, root) and _has_root(den, root):
                num, den = trim(_deflate(num, root)), trim(_deflate(den, root))
                changed = True
                break
    return num, den


def rational_sum(f: tuple, g: tuple) -> tuple:
    """f + g of two rationals (num, den), common factors cancelled."""
    return cancel(np.polyadd(polymul(f[0], g[1]), polymul(g[0], f[1])), polymul(f[1], g[1]))


def rational_product(f: tuple, g: tuple) -> tuple:
    """f g of two rationals (num, den), common factors cancelled."""
    return cancel(polymul(f[0], g[0]), polymul(f[1], g[1]))


#: the rational 0 (0 / 1)
ZERO = (np.zeros(1), np.ones(1))
