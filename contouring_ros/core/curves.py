"""Parametric reference contours R(theta) with analytic derivatives.

Every curve maps a scalar parameter ``theta`` over ``domain`` to a point in R^n and gives the first three
derivatives with respect to ``theta`` analytically (papers 000 eq. 3, 003 eq. 1-5 need up to the third).
"""
from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

__all__ = ["Curve", "Parabola", "Line", "Circle"]


class Curve(ABC):
    """A smooth parametric contour R(theta) in R^dimension.

    Subclasses implement :meth:`derivatives`. ``domain`` is the parameter interval the contour covers;
    ``closed`` curves repeat with period ``domain[1] - domain[0]``.
    """

    dimension: int
    domain: tuple[float, float]
    closed: bool = False

    @abstractmethod
    def columns(self, theta) -> list:
        """[R, dR, d2R, d3R] at theta (derivatives by theta), each a tuple with one entry per coordinate.

        The entries are floats for a float theta (the fast scalar path the estimators iterate on) and
        arrays for an array theta.
        """

    def derivatives(self, theta, order: int = 2) -> np.ndarray:
        """R and its derivatives up to ``order`` (<= 3).

        Parameters
        ----------
        theta : float or array_like, shape (m,)
            Curve parameter(s).
        order : int
            Highest derivative returned.

        Returns
        -------
        ndarray, shape (order + 1, dimension) for scalar theta, (order + 1, m, dimension) otherwise.
            ``out[j]`` is d^j R / d theta^j.
        """
        theta = np.asarray(theta, dtype=float) if np.ndim(theta) else theta
        return _stack(self.columns(theta), theta, order)

    def point(self, theta) -> np.ndarray:
        """R(theta): shape (dimension,) or (m, dimension)."""
        return self.derivatives(theta, order=0)[0]

    def wrap_scalar(self, theta: float) -> float:
        """:meth:`wrap` for one float (the estimators' inner loops)."""
        lo, hi = self.domain
        return lo + (theta - lo) % (hi - lo) if self.closed else min(max(theta, lo), hi)

    def wrap(self, theta):
        """Map theta into the domain (periodically for closed curves, by clipping otherwise)."""
        if np.ndim(theta) == 0:
            return self.wrap_scalar(theta)
        lo, hi = self.domain
        if self.closed:
            return lo + np.mod(np.asarray(theta, dtype=float) - lo, hi - lo)
        return np.clip(theta, lo, hi)


def _stack(columns, theta, order):
    """Assemble per-axis derivative columns into the (order+1, [m,] dim) layout."""
    rows = columns[: order + 1]
    if np.ndim(theta) == 0:
        return np.array(rows, dtype=float)
    out = np.empty((order + 1,) + np.shape(theta) + (len(rows[0]),))
    for j, row in enumerate(rows):
        for i, value in enumerate(row):
            out[j, ..., i] = value
    return out


class Parabola(Curve):
    """Parabola R = [theta, h theta^2] over theta in [-a, a] (paper 000, section IV).

    Parameters
    ----------
    a : float
        Half-width of the parameter range [m].
    h : float
        Curvature coefficient [1/m]; the curvature at the vertex is 2h.
    """

    dimension = 2

    def __init__(self, a: float, h: float):
        self.a = float(a)
        self.h = float(h)
        self.domain = (-self.a, self.a)

    def columns(self, t) -> list:
        h = self.h
        return [(t, h * t * t), (1.0, 2.0 * h * t), (0.0, 2.0 * h), (0.0, 0.0)]


class Line(Curve):
    """Straight line from ``start`` to ``end`` parametrised by arc length theta in [0, L]."""

    def __init__(self, start, end):
        self.start = np.asarray(start, dtype=float)
        self.end = np.asarray(end, dtype=float)
        if self.start.shape != self.end.shape or self.start.ndim != 1:
            raise ValueError("line start and end must be points of the same dimension")
        length = float(np.linalg.norm(self.end - self.start))
        if length <= 0.0:
            raise ValueError("line start and end must differ")
        self.dimension = self.start.size
        self.direction = (self.end - self.start) / length
        self._start, self._direction = tuple(self.start.tolist()), tuple(self.direction.tolist())
        self.domain = (0.0, length)

    def columns(self, t) -> list:
        start, direction = self._start, self._direction
        return [tuple(s + t * d for s, d in zip(start, direction)), direction,
                (0.0,) * self.dimension, (0.0,) * self.dimension]


class Circle(Curve):
    """Circle R = c + r [cos theta, sin theta], theta in [0, 2 pi), counter-clockwise."""

    dimension = 2
    closed = True

    def __init__(self, radius: float, center=(0.0, 0.0)):
        self.radius = float(radius)
        if self.radius <= 0.0:
            raise ValueError("circle radius must be positive")
        self.center = np.asarray(center, dtype=float)
        self._center = tuple(self.center.tolist())
        self.domain = (0.0, 2.0 * np.pi)

    def columns(self, t) -> list:
        r, (cx, cy) = self.radius, self._center
        c, s = r * np.cos(t), r * np.sin(t)
        return [(cx + c, cy + s), (-s, c), (-c, -s), (s, -c)]
