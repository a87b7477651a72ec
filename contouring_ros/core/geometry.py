"""Differential geometry of the reference contour and the exact contour error.

The exact contour error is the distance from a point to the *whole* reference curve: a global search
over a dense sampling of the curve (a k-d tree), then Newton refinement of the foot point with the full
Hessian of J = |R(theta) - P|^2 / 2 (paper 000 eq. 4, 9, 10). Scoring always uses this, never an
estimator's own output.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .curves import Curve

__all__ = ["unit_tangent", "left_normal", "curvature", "signed_error", "FootPoints", "ExactContourError"]


def unit_tangent(curve: Curve, theta) -> np.ndarray:
    """Unit tangent R'/|R'| at theta (paper 000 eq. 14, U)."""
    d1 = curve.derivatives(theta, order=1)[1]
    return d1 / np.linalg.norm(d1, axis=-1, keepdims=True)


def left_normal(tangent: np.ndarray) -> np.ndarray:
    """The planar normal obtained by turning a 2-D tangent 90 degrees counter-clockwise."""
    tangent = np.asarray(tangent, dtype=float)
    return np.stack([-tangent[..., 1], tangent[..., 0]], axis=-1)


def curvature(curve: Curve, theta) -> np.ndarray:
    """Curvature |R' x R''| / |R'|^3 (paper 003 eq. 2); signed for planar curves (positive turning left)."""
    d = curve.derivatives(theta, order=2)
    d1, d2 = d[1], d[2]
    speed = np.linalg.norm(d1, axis=-1)
    if curve.dimension == 2:
        cross = d1[..., 0] * d2[..., 1] - d1[..., 1] * d2[..., 0]
    else:
        cross = np.linalg.norm(np.cross(d1, d2), axis=-1)
    return cross / speed**3


def signed_error(vector: np.ndarray, tangent: np.ndarray) -> np.ndarray:
    """Scalar contour error from an error vector E = R(theta*) - P.

    Planar curves: E . n with n the left normal of the tangent (positive when the axes run to the right
    of the contour's direction of travel). In more dimensions: |E| (no side is defined).
    """
    vector = np.asarray(vector, dtype=float)
    if vector.shape[-1] == 2:
        return np.sum(vector * left_normal(tangent), axis=-1)
    return np.linalg.norm(vector, axis=-1)


@dataclass(frozen=True)
class FootPoints:
    """Exact contour errors of a batch of points.

    Attributes
    ----------
    theta : ndarray, shape (m,)
        Parameter of the nearest point on the curve (the foot point).
    vector : ndarray, shape (m, n)
        E* = R(theta*) - P, from each point to its foot point.
    distance : ndarray, shape (m,)
        |E*|, the contour error.
    signed : ndarray, shape (m,)
        Signed contour error, see :func:`signed_error`.
    """

    theta: np.ndarray
    vector: np.ndarray
    distance: np.ndarray
    signed: np.ndarray


class ExactContourError:
    """Distance from points to the whole curve: k-d tree global search, then bracketed Newton refinement.

    Parameters
    ----------
    curve : Curve
        The reference contour; its whole ``domain`` is searched.
    samples : int
        Number of dense samples for the global search. The refinement is bracketed between the
        neighbours of the nearest sample, so the result is exact to ``tolerance`` as long as no two
        branches of the curve come closer than the sample spacing.
    tolerance : float
        Newton step size [parameter units] at which the refinement stops.
    """

    def __init__(self, curve: Curve, samples: int = 20001, tolerance: float = 1e-15, max_iterations: int = 50):
        self.curve = curve
        lo, hi = curve.domain
        from scipy.spatial import cKDTree   # imported here: the nodes never need it, and it is slow to load
        self._grid = np.linspace(lo, hi, int(samples))
        self._tree = cKDTree(curve.point(self._grid))
        self.tolerance = float(tolerance)
        self.max_iterations = int(max_iterations)

    def __call__(self, points) -> FootPoints:
        """Exact contour error of ``points`` (shape (m, n) or (n,))."""
        points = np.atleast_2d(np.asarray(points, dtype=float))
        grid = self._grid
        _, nearest = self._tree.query(points)
        lower = grid[np.maximum(nearest - 1, 0)]
        upper = grid[np.minimum(nearest + 1, grid.size - 1)]
        theta = grid[nearest]
        for _ in range(self.max_iterations):
            d = self.curve.derivatives(theta, order=2)
            error = d[0] - points
            gradient = np.sum(error * d[1], axis=-1)                       # paper 000 eq. 9
            hessian = np.sum(error * d[2], axis=-1) + np.sum(d[1] * d[1], axis=-1)  # eq. 10
            hessian = np.where(hessian > 0.0, hessian, np.sum(d[1] * d[1], axis=-1))  # eq. 11 fallback
            step = gradient / hessian
            new_theta = np.clip(theta - step, lower, upper)
            moved = np.abs(new_theta - theta)
            theta = new_theta
            if np.all(moved <= self.tolerance * np.maximum(1.0, np.abs(theta))):
                break
        d = self.curve.derivatives(theta, order=1)
        vector = d[0] - points
        tangent = d[1] / np.linalg.norm(d[1], axis=-1, keepdims=True)
        return FootPoints(theta=theta, vector=vector, distance=np.linalg.norm(vector, axis=-1),
                          signed=signed_error(vector, tangent))
