"""Differential geometry of the reference contour and the exact contour error.

The exact contour error is the distance from a point to the *whole* reference curve: a global search
over a dense sampling of the curve (a k-d tree), then Newton refinement of the foot point with the full
Hessian of J = |R(theta) - P|^2 / 2 (paper 000 eq. 4, 9, 10). Scoring always uses this, never an
estimator's own output.
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass

import numpy as np

from .curves import Curve

__all__ = ["unit_tangent", "left_normal", "curvature", "signed_error", "FrenetFrame", "frenet_axes", "frenet_frame", "frenet_generator",
           "FootPoints", "ExactContourError", "dot", "sum_of_products", "norm", "matvec", "matmul", "dot_rows",
           "matvec_rows", "matmul_rows", "power_rows", "atan2_rows"]


# Products of short vectors and small matrices on the published (one-step, scalar) path. ``a @ b``,
# np.dot and np.linalg.norm of a 1-D array call BLAS, whose rounding (fused multiply-adds, the order of
# the partial sums) depends on how numpy was built: the same experiment then records values one ulp
# apart on two machines. These sum plain float products left to right, in IEEE double arithmetic
# that every build rounds alike (the batch path's elementwise products and short reductions agree with
# them to the last bit or so).

def _floats(a) -> list:
    """A vector or matrix as (nested) Python floats."""
    return np.asarray(a, dtype=float).tolist()


def sum_of_products(a: list, b: list) -> float:
    """a[0] b[0] + a[1] b[1] + ..., left to right, of two lists of floats."""
    total = a[0] * b[0]
    for x, y in zip(a[1:], b[1:]):
        total += x * y
    return total


def dot(a, b) -> float:
    """a . b of two vectors as a float: a[0] b[0] + a[1] b[1] + ..., left to right."""
    return sum_of_products(_floats(a), _floats(b))


def cross3(a, b) -> np.ndarray:
    """a x b of two 3-vectors: (a1 b2 - a2 b1, a2 b0 - a0 b2, a0 b1 - a1 b0), the products and differences
    np.cross forms, in its order, without its per-call overhead."""
    (a0, a1, a2), (b0, b1, b2) = _floats(a), _floats(b)
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def norm(a) -> float:
    """|a| = sqrt(a . a) (see :func:`dot`; sqrt is correctly rounded)."""
    return math.sqrt(dot(a, a))


def matvec(m, v) -> np.ndarray:
    """m v for a small matrix (rows . v, see :func:`dot`)."""
    v = _floats(v)
    return np.array([sum_of_products(row, v) for row in _floats(m)])


def matmul(a, b) -> np.ndarray:
    """a b for small matrices (rows of a . columns of b, see :func:`dot`)."""
    columns = _floats(np.asarray(b, dtype=float).T)
    return np.array([[sum_of_products(row, column) for column in columns] for row in _floats(a)])


# Their batch forms (:mod:`contouring_ros.core.batch`): the same products summed in the same order, one per
# member of a leading batch axis, so that a batch member's numbers are those of the scalar path.

def dot_rows(a, b) -> np.ndarray:
    """:func:`dot` along the last axis of arrays (broadcast over the leading ones): shape without that axis."""
    total = a[..., 0] * b[..., 0]
    for k in range(1, np.shape(a)[-1]):
        total = total + a[..., k] * b[..., k]
    return total


def _pow_or_inf(x: float, exponent: float) -> float:
    try:
        return x ** exponent
    except OverflowError:
        return math.copysign(math.inf, x) if exponent % 2 else math.inf


def _value_by_value(function, *arrays) -> np.ndarray:
    """``function`` of Python floats applied to the broadcast ``arrays`` value by value."""
    arrays = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in arrays))
    shape = arrays[0].shape
    return np.fromiter(map(function, *(a.ravel().tolist() for a in arrays)), float, arrays[0].size).reshape(shape)


# numpy's own power and arctan2 (SIMD ones on AVX-512 builds) differ from the C library's, which the scalar
# path's Python floats call, in the last bit of a few values in a hundred: a batch member would then part
# from its run alone. The batch path computes them value by value as the scalar path does.

def power_rows(x, exponent: float) -> np.ndarray:
    """``x ** exponent`` of an array as Python floats compute it (the C library's pow; an overflow inf)."""
    exponent = float(exponent)
    return _value_by_value(lambda v: _pow_or_inf(v, exponent), x)


def atan2_rows(y, x) -> np.ndarray:
    """``math.atan2`` of arrays, value by value."""
    return _value_by_value(math.atan2, y, x)


def matvec_rows(m, v) -> np.ndarray:
    """:func:`matvec` of a batch: m (..., r, c), v (..., c) -> (..., r)."""
    out = np.empty(np.broadcast_shapes(np.shape(m)[:-1], np.shape(v)[:-1] + (1,)))
    for i in range(out.shape[-1]):
        out[..., i] = dot_rows(m[..., i, :], v)
    return out


def matmul_rows(a, b) -> np.ndarray:
    """:func:`matmul` of a batch: a (..., r, k), b (..., k, c) -> (..., r, c)."""
    out = np.empty(np.broadcast_shapes(np.shape(a)[:-2], np.shape(b)[:-2]) + (np.shape(a)[-2], np.shape(b)[-1]))
    for i in range(out.shape[-2]):
        for j in range(out.shape[-1]):
            out[..., i, j] = dot_rows(a[..., i, :], b[..., :, j])
    return out


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
    if vector.shape == (2,):          # one point: plain floats
        return float(-vector[0] * tangent[1] + vector[1] * tangent[0])
    if vector.ndim == 1:              # one point in 3-D: a plain float
        return norm(vector)
    if vector.shape[-1] == 2:
        return np.sum(vector * left_normal(tangent), axis=-1)
    return np.linalg.norm(vector, axis=-1)


def frenet_axes(curve: Curve, theta: float) -> tuple:
    """The Frenet frame of the contour at one parameter: (R, kappa, tau, |R'|).

    R has the unit tangent alpha, normal beta and (in 3-D) binormal gamma as columns, with curvature and
    torsion from paper 003 eq. 1, 4 and 5: alpha = R'/|R'|, gamma = R' x R'' / |R' x R''|,
    beta = gamma x alpha, kappa = |R' x R''| / |R'|^3, tau = (R', R'', R''') / |R' x R''|^2.
    Planar contours use the 2-D frame [alpha, left normal] and the signed ("relative") curvature of
    paper 003 eq. 27, so the frame never flips where the curve changes its bending direction; tau = 0.
    On a straight 3-D stretch (R' x R'' = 0) beta is any fixed normal and kappa = tau = 0.

    For a batch of parameters theta (B, 1): R (B, n, n) and kappa, tau, |R'| (B, 1), the same formulas
    elementwise.
    """
    if np.ndim(theta):
        return _frenet_axes_rows(curve, theta)
    d = curve.derivatives(float(theta), order=3)
    d1, d2, d3 = d[1], d[2], d[3]
    speed = norm(d1)
    alpha = d1 / speed
    if curve.dimension == 2:
        kappa = float(d1[0] * d2[1] - d1[1] * d2[0]) / speed**3
        a0, a1 = float(alpha[0]), float(alpha[1])
        return np.array([[a0, -a1], [a1, a0]]), kappa, 0.0, speed      # columns: alpha, its left normal
    if curve.dimension != 3:
        raise ValueError("the Frenet frame is defined for planar and spatial (2-D and 3-D) contours")
    cross = cross3(d1, d2)
    cross_norm = norm(cross)
    if cross_norm <= 1e-12 * speed**3:
        helper = np.eye(3)[int(np.argmin(np.abs(alpha)))]
        beta = cross3(cross3(alpha, helper), alpha)
        beta /= norm(beta)
        return np.column_stack([alpha, beta, cross3(alpha, beta)]), 0.0, 0.0, speed
    gamma = cross / cross_norm
    return (np.column_stack([alpha, cross3(gamma, alpha), gamma]), cross_norm / speed**3,
            dot(cross, d3) / cross_norm**2, speed)


def _frenet_axes_rows(curve: Curve, theta) -> tuple:
    """:func:`frenet_axes` at a batch of parameters theta (B, 1)."""
    d = curve.derivatives(np.asarray(theta, dtype=float), order=3)[:, :, 0, :]
    d1, d2, d3 = d[1], d[2], d[3]
    speed = np.sqrt(dot_rows(d1, d1))[:, None]
    alpha = d1 / speed
    if curve.dimension == 2:
        kappa = (d1[:, 0:1] * d2[:, 1:2] - d1[:, 1:2] * d2[:, 0:1]) / power_rows(speed, 3)
        return np.stack([alpha, left_normal(alpha)], axis=-1), kappa, np.zeros_like(kappa), speed
    if curve.dimension != 3:
        raise ValueError("the Frenet frame is defined for planar and spatial (2-D and 3-D) contours")
    cross = np.cross(d1, d2)
    cross_norm = np.sqrt(dot_rows(cross, cross))[:, None]
    speed_cubed = power_rows(speed, 3)
    straight = cross_norm <= 1e-12 * speed_cubed
    with np.errstate(divide="ignore", invalid="ignore"):
        gamma = cross / cross_norm
        rotation = np.stack([alpha, np.cross(gamma, alpha), gamma], axis=-1)
        kappa, tau = cross_norm / speed_cubed, dot_rows(cross, d3)[:, None] / power_rows(cross_norm, 2)
    if straight.any():
        helper = np.eye(3)[np.argmin(np.abs(alpha), axis=-1)]
        beta = np.cross(np.cross(alpha, helper), alpha)
        beta = beta / np.sqrt(dot_rows(beta, beta))[:, None]
        fixed = np.stack([alpha, beta, np.cross(alpha, beta)], axis=-1)
        rotation = np.where(straight[:, :, None], fixed, rotation)
        kappa, tau = np.where(straight, 0.0, kappa), np.where(straight, 0.0, tau)
    return rotation, kappa, tau, speed


@dataclass(frozen=True)
class FrenetFrame:
    """The Frenet frame at the reference point w_d(t) and how it moves (paper 003 eq. 2-5, 19-20).

    Attributes
    ----------
    rotation : ndarray (n, n)
        R = [alpha, beta(, gamma)]: task-frame coordinates f = R^T (w - w_d) (eq. 3).
    curvature, torsion : float
        kappa (signed for planar contours) and tau.
    speed : float
        v = |dw_d/dt|.
    rotation_rate, rotation_acceleration : ndarray (n, n)
        dR/dt = -v R G and d2R/dt2 = -(dv/dt R G + v dR/dt G + v R dG/dt) with
        G = [[0, kappa, 0], [-kappa, 0, tau], [0, -tau, 0]] (the planar block in 2-D).

    For a batch the matrices are (B, n, n) and the scalars (B, 1).
    """

    rotation: np.ndarray
    curvature: float
    torsion: float
    speed: float
    rotation_rate: np.ndarray
    rotation_acceleration: np.ndarray


def frenet_generator(n: int, kappa: float, tau: float) -> np.ndarray:
    """G = [[0, kappa, 0], [-kappa, 0, tau], [0, -tau, 0]] (its planar block for n = 2): dR/dt = -v R G.
    For a batch, kappa and tau (B, 1): G (B, n, n)."""
    if np.ndim(kappa) or np.ndim(tau):
        kappa, tau = (column[:, 0] for column in np.broadcast_arrays(kappa, tau))
        g = np.zeros(kappa.shape + (n, n))
        g[:, 0, 1], g[:, 1, 0] = kappa, -kappa
        if n == 3:
            g[:, 1, 2], g[:, 2, 1] = tau, -tau
        return g
    g = np.zeros((n, n))
    g[0, 1], g[1, 0] = kappa, -kappa
    if n == 3:
        g[1, 2], g[2, 1] = tau, -tau
    return g


def frenet_frame(curve: Curve, theta: float, theta_dot: float, theta_ddot: float = 0.0,
                 relative_step: float = 1e-5) -> FrenetFrame:
    """The moving Frenet frame at R(theta) when theta advances at theta_dot, theta_ddot.

    R and dR/dt are analytic; d2R/dt2 needs d kappa/dt and d tau/dt, which are taken by a central
    difference of kappa(theta) and tau(theta) over +-``relative_step`` of the parameter range (tau' would
    need a fourth derivative of the curve; both are exact for the circle and the helix, whose kappa and
    tau are constant).

    For a batch, theta, theta_dot and theta_ddot (B, 1) (:mod:`contouring_ros.core.batch`): the same
    formulas on each member.
    """
    if np.ndim(theta):
        return _frenet_frame_rows(curve, theta, theta_dot, theta_ddot, relative_step)
    rotation, kappa, tau, speed_theta = frenet_axes(curve, theta)
    n = rotation.shape[0]
    d = curve.derivatives(float(theta), order=2)
    speed = speed_theta * theta_dot
    speed_rate = dot(d[1], d[2]) / speed_theta * theta_dot**2 + speed_theta * theta_ddot
    h = relative_step * max(abs(curve.domain[1] - curve.domain[0]), 1e-9)
    _, kappa_plus, tau_plus, _ = frenet_axes(curve, theta + h)
    _, kappa_minus, tau_minus, _ = frenet_axes(curve, theta - h)
    g = frenet_generator(n, kappa, tau)
    g_rate = frenet_generator(n, (kappa_plus - kappa_minus) / (2 * h) * theta_dot,
                               (tau_plus - tau_minus) / (2 * h) * theta_dot)
    rate = matmul(-speed * rotation, g)
    acceleration = -(matmul(speed_rate * rotation, g) + matmul(speed * rate, g) + matmul(speed * rotation, g_rate))
    return FrenetFrame(rotation, kappa, tau, speed, rate, acceleration)


def _frenet_frame_rows(curve: Curve, theta, theta_dot, theta_ddot, relative_step: float) -> FrenetFrame:
    """:func:`frenet_frame` at a batch of parameters theta (B, 1)."""
    theta = np.asarray(theta, dtype=float)
    rotation, kappa, tau, speed_theta = _frenet_axes_rows(curve, theta)
    n = rotation.shape[-1]
    d = curve.derivatives(theta, order=2)[:, :, 0, :]
    speed = speed_theta * theta_dot
    speed_rate = dot_rows(d[1], d[2])[:, None] / speed_theta * power_rows(theta_dot, 2) + speed_theta * theta_ddot
    h = relative_step * np.maximum(np.abs(curve.domain[1] - curve.domain[0]), 1e-9)
    _, kappa_plus, tau_plus, _ = _frenet_axes_rows(curve, theta + h)
    _, kappa_minus, tau_minus, _ = _frenet_axes_rows(curve, theta - h)
    g = frenet_generator(n, kappa, tau)
    g_rate = frenet_generator(n, (kappa_plus - kappa_minus) / (2 * h) * theta_dot,
                               (tau_plus - tau_minus) / (2 * h) * theta_dot)
    v, v_rate = speed[:, :, None], speed_rate[:, :, None]
    rate = matmul_rows(-v * rotation, g)
    acceleration = -(matmul_rows(v_rate * rotation, g) + matmul_rows(v * rate, g) + matmul_rows(v * rotation, g_rate))
    return FrenetFrame(rotation, kappa, tau, speed, rate, acceleration)


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


_TREES: dict = {}      # the search trees of the curves scored last, by their samples' digest
_TREES_KEPT = 16


def _search_tree(samples: np.ndarray):
    """A k-d tree over a curve's dense ``samples``, shared by every solver of the same samples: a tuning
    scores thousands of runs of one curve, each run building its own curve object."""
    samples = np.ascontiguousarray(samples, dtype=float)
    key = (samples.shape, hashlib.blake2b(samples.tobytes(), digest_size=16).digest())
    tree = _TREES.get(key)
    if tree is None:
        from scipy.spatial import cKDTree   # imported here: the nodes never need it, and it is slow to load
        if len(_TREES) >= _TREES_KEPT:
            _TREES.pop(next(iter(_TREES)))
        tree = _TREES[key] = cKDTree(samples)
    return tree


def _cell_keys(rows, positions, size: float) -> np.ndarray:
    """One integer per (row, cell of side ``size`` that ``positions`` lie in): equal exactly for equal pairs."""
    cells = np.floor(positions / max(size, 1e-300)).astype(np.int64)
    if not len(rows):
        return np.zeros(0, dtype=np.int64)
    cells -= cells.min(axis=0)
    spans = cells.max(axis=0) + 1
    if float(np.prod(spans.astype(float))) * (float(rows.max()) + 1.0) < 2.0 ** 62:
        key = rows.astype(np.int64)
        for column, span in zip(cells.T, spans):
            key = key * span + column
        return key
    return np.unique(np.column_stack([rows, cells]), axis=0, return_inverse=True)[1].reshape(-1)


def _tangents_and_curvatures(curve: Curve, theta) -> tuple:
    """(unit tangents, curvature vectors) of ``curve`` at the parameters ``theta``: t = c' / |c'| and
    k = (c'' - (c''.t) t) / |c'|^2 (zero where c' vanishes)."""
    d = curve.derivatives(theta, order=2)
    speed = np.linalg.norm(d[1], axis=-1, keepdims=True)
    safe = np.where(speed > 0.0, speed, 1.0)
    tangent = np.where(speed > 0.0, d[1] / safe, 0.0)
    normal_part = d[2] - np.sum(d[2] * tangent, axis=-1, keepdims=True) * tangent
    return tangent, np.where(speed > 0.0, normal_part / safe ** 2, 0.0)


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
    window : float, optional
        Restrict each point's search to parameters within +-window of the parameter given with it
        (``near``); default: the curve's ``contour_error_window`` (0: the whole curve).

    Other branches. Where the whole curve is searched, each point's refined distance D is checked against
    every other stretch of the curve that could come nearer: any point of the curve lies within half the
    largest sample spacing s of a sample, so a nearer foot point has a sample within D + s/2 of the point.
    The samples there that are not the refinement's own bracket (the nearest :attr:`BRANCH_CANDIDATES`
    asked for first, four times as many where all of them lie within that distance) are refined too, one
    per cell of s/2 (a path gone round one circle many times has a sample of each lap there, all with one
    foot point): the one whose stretch passes nearest the point to second order (the distance from the
    curve's expansion about it with its tangent and curvature), so that a stretch that ends among the laps'
    samples is refined, not a lap; and the nearest foot point kept. Without it a point near where a path
    comes back close to itself (a lead-in line that ends where 80 laps of a circle of a million chords begin,
    sampled every 0.25 mm) was given another branch's distance.

    Corners. Where the tangent turns by more than :attr:`TURN` between neighbouring samples (a tool path's
    exact-stop corner, a blend arc of microns), the distance along the curve has a minimum either side and
    Newton's steps stay on the side they start: such brackets are also refined from their ends (see
    :meth:`_refine`). A corner that turns by less between samples, or a feature shorter than the sample
    spacing (a notch of microns on a long path), is not seen, and a point near it can be given up to a few
    micrometres too much (a 0.24 rad corner of two 0.5 m lines: 10 um); finding corners from a tool path's
    own segment joints would remove that.

    Far points. A k-d tree's nearest-sample search costs about as many samples as lie within the point's
    distance of it: a point millimetres off the path (a run that nearly diverged) costs 10-100x a point on it.
    A point farther than :attr:`FAR` spacings of every :attr:`COARSE`-th sample from every sample (the first
    search, bounded at that distance, finds none) is searched among those coarse samples instead, and its
    Newton refinement bracketed by the coarse sample's neighbours. Its distance is then the distance to the
    curve's nearest point in that bracket: the true one, unless another branch's minimum lies within
    h^2 (1/D + kappa) / 8 of it (h the coarse spacing, D the distance, kappa the curvature; with D >= FAR h,
    a share of at most 1 / (8 FAR^2) + h kappa / (8 FAR) of D, 1e-5 here). Its other branches are looked for
    among the coarse samples too, within D and half the largest coarse interval's arc, each refined within
    its coarse neighbours: within a far point's distance lie most of the curve's dense samples (a run 20 mm
    off a 45 mm path: all 20001), and their search cost 0.5 s a run. Every other point's result is the
    dense search's.
    """

    CANDIDATES = 64   # nearest samples examined per point when a window restricts the search
    BRANCH_CANDIDATES = 8    # samples first asked for within D + s/2 of a point, for a nearer branch (see above)
    CHUNK = 4096             # points whose other branches are looked for at once (memory)
    HALVINGS = 60     # a descending Newton step is halved at most this often
    TURN = 0.25       # [rad] a tangent turning by more between neighbouring samples: a bracket across a corner
    COARSE = 8        # every COARSE-th sample makes the search of far points
    WIDE = 4          # other branches within more than WIDE coarse half spacings are found through the coarse samples
    FAR = 128         # ... for points farther than FAR of its spacings from every sample

    def __init__(self, curve: Curve, samples: int = 20001, tolerance: float = 1e-15, max_iterations: int = 50,
                 window: float | None = None):
        self.curve = curve
        lo, hi = curve.domain
        self._grid = np.linspace(lo, hi, int(samples))
        samples = curve.point(self._grid)
        self._tree = _search_tree(samples)
        self._coarse = np.arange(0, len(self._grid), self.COARSE)
        coarse = samples[self._coarse]
        self._coarse_tree = _search_tree(coarse) if len(coarse) > 1 else None
        self._far = self.FAR * float(np.max(np.linalg.norm(np.diff(coarse, axis=0), axis=-1))) if len(coarse) > 1 \
            else math.inf
        # half the largest spacing of neighbouring samples, with a margin for the arc between them
        self._half_spacing = 0.6 * float(np.max(np.linalg.norm(np.diff(samples, axis=0), axis=-1))) \
            if len(samples) > 1 else 0.0
        # ... and of the coarse samples, each interval's arc taken as the sum of its dense chords
        chords = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(samples, axis=0), axis=-1))]) \
            if len(samples) > 1 else np.zeros(len(samples))
        self._coarse_half_spacing = 0.6 * float(np.max(np.diff(chords[self._coarse]))) if len(coarse) > 1 else 0.0
        self._samples = samples
        self._sample_tangent, self._sample_curvature = _tangents_and_curvatures(curve, self._grid)
        # intervals between neighbouring samples where the tangent turns by more than TURN (a corner of a
        # tool path, a blend arc of microns), as a running count: a bracket holds one where the count moves
        turning = np.sum(self._sample_tangent[1:] * self._sample_tangent[:-1], axis=-1) < math.cos(self.TURN)
        self._turns = np.concatenate([[0], np.cumsum(turning)])
        self.tolerance = float(tolerance)
        self.max_iterations = int(max_iterations)
        self.window = float(curve.contour_error_window if window is None else window)

    def _nearest_in_window(self, points, near) -> np.ndarray:
        """Index of each point's nearest sample among those within +-window of its ``near`` parameter: the
        nearest sample where it lies inside (most points), else the nearest of :attr:`CANDIDATES` inside,
        else the nearest."""
        near = np.asarray(near, dtype=float).reshape(-1)
        _, nearest = self._tree.query(points)
        outside = np.flatnonzero(~self._inside(nearest, near))
        if outside.size:
            _, candidates = self._tree.query(points[outside], k=min(self.CANDIDATES, self._grid.size))
            candidates = candidates.reshape(outside.size, -1)
            inside = self._inside(candidates, near[outside].reshape(-1, 1))
            first = np.argmax(inside, axis=1)                 # candidates come nearest first
            chosen = candidates[np.arange(outside.size), first]
            nearest[outside] = np.where(inside.any(axis=1), chosen, candidates[:, 0])
        return nearest

    def _nearest(self, points) -> tuple:
        """(each point's nearest sample, how many samples either side bracket its refinement): the dense
        search's nearest sample and 1, or for a far point (see the class docstring) the nearest coarse sample
        and :attr:`COARSE`."""
        distance, nearest = self._tree.query(points, distance_upper_bound=self._far)
        far = ~np.isfinite(distance)
        if not far.any():
            return nearest, 1
        _, coarse = self._coarse_tree.query(points[far])
        nearest[far] = self._coarse[coarse]
        reach = np.ones(len(points), dtype=int)
        reach[far] = self.COARSE
        return nearest, reach

    def _inside(self, samples, near) -> np.ndarray:
        """Whether the grid ``samples`` (indices) lie within +-window of the parameters ``near``."""
        offset = self._grid[samples] - near
        if self.curve.closed:
            period = self.curve.domain[1] - self.curve.domain[0]
            offset = (offset + period / 2) % period - period / 2
        return np.abs(offset) <= self.window

    def _refine(self, points, nearest, reach) -> np.ndarray:
        """Each point's foot-point parameter: Newton's steps on the squared distance (paper 000 eqs. 9-11)
        from the sample ``nearest``, bracketed by the samples ``reach`` either side of it. Where the tangent
        turns by more than :attr:`TURN` within the bracket (a corner, or a blend arc of microns), the distance
        along the curve has a minimum on each side of the turn and Newton's steps stay on the side they start
        (from the far side of a square corner they stop at the corner): there the steps are also made from the
        bracket's two ends, and from the sample once more with each step shortened until the distance falls
        (so that steps that overshoot a corner, the nearest point there, come back to it instead of leaping
        from side to side); the nearest of the four foot points is kept."""
        grid = self._grid
        nearest = np.asarray(nearest)
        low, high = np.maximum(nearest - reach, 0), np.minimum(nearest + reach, grid.size - 1)
        lower, upper = grid[low], grid[high]
        theta = self._newton(points, grid[nearest], lower, upper)
        turned = np.flatnonzero(self._turns[high] > self._turns[low])
        if turned.size:
            here = points[turned]
            best = theta[turned]
            gap = np.linalg.norm(self.curve.point(best) - here, axis=-1)
            for start, descent in ((low, False), (high, False), (nearest, True)):
                other = self._newton(here, grid[start[turned]], lower[turned], upper[turned], descent)
                other_gap = np.linalg.norm(self.curve.point(other) - here, axis=-1)
                nearer = other_gap < gap
                best, gap = np.where(nearer, other, best), np.where(nearer, other_gap, gap)
            theta[turned] = best
        return theta

    def _newton(self, points, theta, lower, upper, descent: bool = False) -> np.ndarray:
        """Newton's steps on each point's squared distance from the parameters ``theta``, each clipped to its
        bracket [lower, upper], until they settle (at most :attr:`max_iterations`); with ``descent`` each step
        halved (up to :attr:`HALVINGS` times) until the distance falls, and not made where it never does."""
        theta = np.array(theta, dtype=float)
        active = np.arange(len(points))          # the points whose Newton step has not yet settled
        value = np.sum((self.curve.point(theta) - points) ** 2, axis=-1) if descent else None
        for _ in range(self.max_iterations):
            here = theta[active]
            d = self.curve.derivatives(here, order=2)
            error = d[0] - points[active]
            gradient = np.sum(error * d[1], axis=-1)                       # paper 000 eq. 9
            hessian = np.sum(error * d[2], axis=-1) + np.sum(d[1] * d[1], axis=-1)  # eq. 10
            hessian = np.where(hessian > 0.0, hessian, np.sum(d[1] * d[1], axis=-1))  # eq. 11 fallback
            new_theta = np.clip(here - gradient / hessian, lower[active], upper[active])
            if descent:
                new_theta = self._descending(points[active], here, new_theta, value, active)
            theta[active] = new_theta
            moving = np.abs(new_theta - here) > self.tolerance * np.maximum(1.0, np.abs(new_theta))
            active = active[moving]
            if not active.size:
                break
        return theta

    def _nearer_branches(self, points, theta, distance, nearest, reach) -> np.ndarray:
        """Replace in ``theta`` each foot point (at ``distance``) that another stretch of the curve beats (see
        the class docstring, "Other branches"), :attr:`CHUNK` points at a time, far points (``reach`` above 1)
        among the coarse samples; the rows replaced."""
        reach = np.broadcast_to(np.asarray(reach), (len(points),))
        replaced = []
        far = reach > 1
        for rows_of_kind, coarse in ((np.flatnonzero(~far), False), (np.flatnonzero(far), True)):
            for start in range(0, rows_of_kind.size, self.CHUNK):
                rows = rows_of_kind[start:start + self.CHUNK]
                better = self._other_branch(points[rows], distance[rows], nearest[rows], reach[rows], coarse)
                if better is not None:
                    here, alternative = better
                    theta[rows[here]] = alternative
                    replaced.append(rows[here])
        return np.concatenate(replaced) if replaced else np.zeros(0, dtype=int)

    def _samples_within(self, points, radius, coarse: bool) -> tuple:
        """(rows, sample indices): every sample (``coarse``: every coarse sample, as its dense index) within
        ``radius[row]`` of ``points[row]``, the nearest :attr:`BRANCH_CANDIDATES` asked for first, four times
        as many where all of them lie within."""
        tree, index = (self._coarse_tree, self._coarse) if coarse else (self._tree, None)
        size = len(self._coarse) if coarse else self._grid.size
        rows, samples = [np.zeros(0, dtype=int)], [np.zeros(0, dtype=int)]
        asked, k = np.arange(len(points)), min(self.BRANCH_CANDIDATES, size)
        while asked.size:
            found, candidates = tree.query(points[asked], k=k, distance_upper_bound=float(np.max(radius[asked])))
            found, candidates = found.reshape(asked.size, -1), candidates.reshape(asked.size, -1)
            inside = found <= radius[asked, None]
            full = inside[:, -1] & (k < size)     # every candidate inside: there may be more
            here, columns = np.nonzero(inside & ~full[:, None])
            rows.append(asked[here])
            samples.append(candidates[here, columns] if index is None else index[candidates[here, columns]])
            asked, k = asked[full], min(4 * k, size)
        return np.concatenate(rows), np.concatenate(samples)

    def _dense_within(self, points, radius) -> tuple:
        """(rows, sample indices): every dense sample within ``radius[row]`` of ``points[row]``, found through
        the coarse samples where the radius spans many dense ones: the dense samples from each coarse sample
        to the next (each interval's arc at most twice the coarse half spacing) of every coarse sample within
        the radius and that arc, kept where within the radius. The same samples as the dense search, at a
        share of its cost for a point far off the path."""
        wide = radius > self.WIDE * self._coarse_half_spacing if self._coarse_tree is not None \
            else np.zeros(len(points), dtype=bool)
        narrow = np.flatnonzero(~wide)
        rows, samples = self._samples_within(points[narrow], radius[narrow], coarse=False)
        out_rows, out_samples = [narrow[rows]], [samples]
        wide = np.flatnonzero(wide)
        if wide.size:
            rows, owners = self._samples_within(points[wide], radius[wide] + 2.0 * self._coarse_half_spacing, True)
            dense = owners[:, None] + np.arange(self.COARSE)
            rows = np.broadcast_to(rows[:, None], dense.shape)
            real = dense < self._grid.size
            rows, dense = rows[real], dense[real]
            near = np.linalg.norm(self._samples[dense] - points[wide[rows]], axis=-1) <= radius[wide[rows]]
            out_rows.append(wide[rows[near]])
            out_samples.append(dense[near])
        return np.concatenate(out_rows), np.concatenate(out_samples)

    def _other_branch(self, points, distance, nearest, reach, coarse: bool = False):
        """(rows, their foot-point parameters) where another branch is nearer than ``distance``, or None. With
        ``coarse`` (far points) the samples looked among are the coarse ones, within ``distance`` plus half the
        coarse spacing, each refined within its coarse neighbours: a far point's bracket already is one, and
        the dense samples within a far point's distance can be most of the curve's."""
        half, width = (self._coarse_half_spacing, self.COARSE) if coarse else (self._half_spacing, 1)
        radius = distance + half
        rows, samples = (self._samples_within(points, radius, True) if coarse
                         else self._dense_within(points, radius))
        other = np.abs(samples - nearest[rows]) > reach[rows]
        rows, samples = rows[other], samples[other]
        if not rows.size:
            return None
        # samples of laps over one stretch (a path gone round one circle many times) give one foot point:
        # one candidate per point and cell of half the spacing, the one whose stretch passes nearest the
        # point to second order (where a lead-in ends among the laps' samples, the lead-in's); a sample whose
        # bracket holds a turn of the tangent (a corner) is refined on its own
        low, high = np.maximum(samples - width, 0), np.minimum(samples + width, self._grid.size - 1)
        alone = self._turns[high] > self._turns[low]
        merged = np.flatnonzero(~alone)
        key = _cell_keys(rows[merged], self._samples[samples[merged]], half)
        order = np.lexsort((self._second_order_distance(points[rows[merged]], samples[merged]), key))
        first = merged[order[np.concatenate([[True], key[order][1:] != key[order][:-1]])]] if merged.size \
            else merged
        kept = np.concatenate([first, np.flatnonzero(alone)])
        rows, samples = rows[kept], samples[kept]
        alternative = self._refine(points[rows], samples, width)
        gap = np.linalg.norm(self.curve.point(alternative) - points[rows], axis=-1)
        order = np.lexsort((gap, rows))
        best = order[np.unique(rows[order], return_index=True)[1]]        # each point's nearest
        better = best[gap[best] < distance[rows[best]]]
        return rows[better], alternative[better]

    def _descending(self, points, here, proposed, value, active) -> np.ndarray:
        """The steps ``here`` -> ``proposed`` halved until each point's squared distance is below its
        ``value[active]`` (``value`` updated), or, where it never is (or the step falls below the tolerance
        first), no step."""
        step = proposed - here
        new = proposed.copy()
        new_value = np.sum((self.curve.point(new) - points) ** 2, axis=-1)
        # a step that changes the distance by rounding alone (a settled point) is made as it is
        bound = value[active] * (1.0 + 1e-12)
        worse, refused = np.flatnonzero(new_value > bound), []
        for _ in range(self.HALVINGS):
            if not worse.size:
                break
            step[worse] *= 0.5
            tiny = np.abs(step[worse]) <= self.tolerance * np.maximum(1.0, np.abs(here[worse]))
            refused.append(worse[tiny])
            worse = worse[~tiny]
            if not worse.size:
                break
            new[worse] = here[worse] + step[worse]
            new_value[worse] = np.sum((self.curve.point(new[worse]) - points[worse]) ** 2, axis=-1)
            worse = worse[new_value[worse] > bound[worse]]
        refused = np.concatenate(refused + [worse])
        new[refused], new_value[refused] = here[refused], value[active][refused]
        value[active] = np.minimum(new_value, value[active])
        return new

    def _second_order_distance(self, points, samples) -> np.ndarray:
        """Each point's distance from the curve's second-order expansion about its sample: with q the point
        less the sample, t the unit tangent and k the curvature vector there, |q - (q.t) t - (q.t)^2 k / 2|,
        the distance to that stretch of the curve within O(h^3) for a foot point h along it."""
        q = points - self._samples[samples]
        along = np.sum(q * self._sample_tangent[samples], axis=-1, keepdims=True)
        return np.linalg.norm(q - along * self._sample_tangent[samples]
                              - 0.5 * along ** 2 * self._sample_curvature[samples], axis=-1)

    def __call__(self, points, near=None) -> FootPoints:
        """Exact contour error of ``points`` (shape (m, n) or (n,)); ``near`` gives each point's reference
        parameter, used when the search is restricted to a window."""
        points = np.atleast_2d(np.asarray(points, dtype=float))
        windowed = self.window > 0.0 and near is not None
        if windowed:
            theta = self._refine(points, self._nearest_in_window(points, near), 1)
        else:
            nearest, reach = self._nearest(points)
            theta = self._refine(points, nearest, reach)
        d = self.curve.derivatives(theta, order=1)
        if not windowed:
            replaced = self._nearer_branches(points, theta, np.linalg.norm(d[0] - points, axis=-1), nearest, reach)
            if replaced.size:
                d[:, replaced] = self.curve.derivatives(theta[replaced], order=1)
        vector = d[0] - points
        tangent = d[1] / np.linalg.norm(d[1], axis=-1, keepdims=True)
        return FootPoints(theta=theta, vector=vector, distance=np.linalg.norm(vector, axis=-1),
                          signed=signed_error(vector, tangent))
