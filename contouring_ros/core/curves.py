"""Parametric reference contours R(theta) with analytic derivatives.

Every curve maps a scalar parameter ``theta`` over ``domain`` to a point in R^n and gives the first three
derivatives with respect to ``theta`` analytically (papers 000 eq. 3, 003 eq. 1-5 need up to the third).
"""
from __future__ import annotations

import math
from abc import ABC, abstractmethod

import numpy as np

from .line_runs import LineItems, StretchChunk, blend_radius
from .path_tables import SEGMENT_KINDS, PathBlock, SegmentTable, StretchTable

__all__ = ["Curve", "Parabola", "Line", "Circle", "Ellipse", "FigureEight", "Saddle", "Helix", "Butterfly", "SplineCurve", "ToolPath",
           "PathBlock", "MAX_PATH_LENGTH", "segment_columns"]


def _scalar_or_array(scalar, array):
    """``scalar`` (the math module's) for a Python float, ``array`` for anything else: one step's curve
    evaluation is a few dozen float operations, which math does at a fraction of the cost of numpy scalars,
    with the same results (tests/core/test_curves_geometry.py checks every curve's scalar path against its
    array path, bit for bit). A float the math function refuses (sin of an infinity, an exp that overflows:
    a diverging run) goes to ``array``, which gives nan or inf as before."""
    def function(x):
        if x.__class__ is float:
            try:
                return scalar(x)
            except (ValueError, OverflowError):
                pass
        return array(x)
    function.__name__ = array.__name__
    return function


def _exp_or_inf(x: float) -> float:
    try:
        return math.exp(x)
    except OverflowError:
        return math.inf


def _libm_exp(x):
    """exp of an array or a numpy scalar by the C library's exp, element by element (anything else: numpy's).
    numpy's float64 sin and cos agree with the C library's bit for bit, but where numpy has a SIMD exp of its
    own (its AVX-512 builds) that exp differs from the C library's in the last bit of about one value in
    twenty: the butterfly's batch and its run alone (math's exp) would then part in the last digits. About
    0.5 us more for a batch's column, 40 ns a value on long arrays (a run's scoring)."""
    if isinstance(x, np.floating):
        return np.float64(_exp_or_inf(float(x)))
    if x.__class__ is not np.ndarray:
        return np.exp(x)
    return np.fromiter(map(_exp_or_inf, x.ravel().tolist()), float, x.size).reshape(x.shape)


_sin, _cos = (_scalar_or_array(getattr(math, name), getattr(np, name)) for name in ("sin", "cos"))
_exp = _scalar_or_array(math.exp, _libm_exp)


# Each analytic curve's columns, (R, R', R'', R''') as a tuple of tuples, as a plain function of theta and the curve's
# numbers (``Curve.formula``): the curve's own columns() for a float or an array theta (with the sin, cos
# and exp above), and, compiled by numba with the math module's, the Newton estimate's kernel
# (:mod:`contouring_ros.core.kernels`): one home for each formula.

def _parabola(t, p):
    """:meth:`Parabola.columns` at t for the parameters (h)."""
    h = p[0]
    return ((t, h * t * t), (1.0, 2.0 * h * t), (0.0, 2.0 * h), (0.0, 0.0))


def _circle(t, p):
    """:meth:`Circle.columns` at t for the parameters (radius, cx, cy)."""
    r, cx, cy = p[0], p[1], p[2]
    c, s = r * _cos(t), r * _sin(t)
    return ((cx + c, cy + s), (-s, c), (-c, -s), (s, -c))


def _ellipse(t, p):
    """:meth:`Ellipse.columns` at t for the parameters (a, b, cx, cy)."""
    a, b, cx, cy = p[0], p[1], p[2], p[3]
    ca, sb = a * _cos(t), b * _sin(t)
    sa, cb = a * _sin(t), b * _cos(t)
    return ((cx + ca, cy + sb), (-sa, cb), (-ca, -sb), (sa, -cb))


def _figure_eight(t, p):
    """:meth:`FigureEight.columns` at t for the parameters (a, b, cx, cy)."""
    a, b, cx, cy = p[0], p[1], p[2], p[3]
    c1, s1, c2, s2 = _cos(t), _sin(t), _cos(2.0 * t), _sin(2.0 * t)
    return ((cx + a * (1.0 - c1), cy + b * s2), (a * s1, 2.0 * b * c2), (a * c1, -4.0 * b * s2),
            (-a * s1, -8.0 * b * c2))


def _helix(t, p):
    """:meth:`Helix.columns` at t for the parameters (a, b, c, omega)."""
    a, b, c, w = p[0], p[1], p[2], p[3]
    cw, sw = _cos(w * t), _sin(w * t)
    zero = 0.0 * t
    return ((a * cw, b * sw, c * t), (-a * w * sw, b * w * cw, c + zero),
            (-a * w * w * cw, -b * w * w * sw, zero), (a * w**3 * sw, -b * w**3 * cw, zero))


def _saddle(t, p):
    """:meth:`Saddle.columns` at t for the parameters (a, b, h, omega)."""
    a, b, h, w = p[0], p[1], p[2], p[3]
    c1, s1, c2, s2 = _cos(w * t), _sin(w * t), _cos(2 * w * t), _sin(2 * w * t)
    return ((a * c1, b * s1, h * c2), (-a * w * s1, b * w * c1, -2 * h * w * s2),
            (-a * w * w * c1, -b * w * w * s1, -4 * h * w * w * c2),
            (a * w**3 * s1, -b * w**3 * c1, 8 * h * w**3 * s2))


def _butterfly(u, p):
    """:meth:`Butterfly.columns` at u for the parameters (scale, cx, cy)."""
    k, cx, cy = p[0], p[1], p[2]
    s, c, e = _sin(u), _cos(u), _exp(_cos(u))
    s4, c4 = _sin(4 * u), _cos(4 * u)
    r = e - 2 * c4
    r1 = -s * e + 8 * s4
    r2 = (s * s - c) * e + 32 * c4
    r3 = s * e * (1 + 3 * c - s * s) - 128 * s4
    return ((cx + k * r * s, cy + k * r * c),
            (k * (r1 * s + r * c), k * (r1 * c - r * s)),
            (k * (r2 * s + 2 * r1 * c - r * s), k * (r2 * c - 2 * r1 * s - r * c)),
            (k * (r3 * s + 3 * r2 * c - 3 * r1 * s - r * c), k * (r3 * c - 3 * r2 * s - 3 * r1 * c + r * s)))


class Curve(ABC):
    """A smooth parametric contour R(theta) in R^dimension.

    Subclasses implement :meth:`derivatives`. ``domain`` is the parameter interval the contour covers;
    ``closed`` curves repeat with period ``domain[1] - domain[0]``.
    """

    dimension: int
    domain: tuple[float, float]
    closed: bool = False
    #: Half-width, in curve parameter, of the stretch around the reference point against which the exact
    #: contour error is measured (0: the whole curve). For self-crossing contours (the butterfly), so that a
    #: point near a crossing is measured against its own branch, as paper 003 section IV-A measures
    #: "in the neighborhood of the current desired point".
    contour_error_window: float = 0.0
    #: nothing in a run writes to a curve: one object can serve a batch as it is (core/batch.py, stack)
    batch_read_only = True
    #: the curve's :meth:`columns` as a plain function ``formula(theta, parameters)`` of the numbers in
    #: :attr:`parameters`, whose scalar path numba can compile (the Newton estimate's kernel,
    #: :mod:`contouring_ros.core.kernels`, runs this same code); None for a curve without one
    formula = None
    #: the numbers :attr:`formula` reads, a tuple of the curve's own attributes (floats; arrays (B, 1) for a
    #: batch's stacked curve)
    parameters = ()

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
        theta = theta if theta.__class__ is float or not np.ndim(theta) else np.asarray(theta, dtype=float)
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
    if theta.__class__ is float or np.ndim(theta) == 0:
        return np.array(rows, dtype=float)
    out = np.empty((order + 1,) + np.shape(theta) + (len(rows[0]),))
    for j, row in enumerate(rows):
        for i, value in enumerate(row):
            out[j, ..., i] = value
    return out


class PlanarLoop(Curve):
    """A closed planar curve over theta in [0, 2 pi), placed at ``center`` (the shared part of the circle,
    ellipse, figure-8 and butterfly)."""

    dimension = 2
    closed = True

    def __init__(self, center=(0.0, 0.0)):
        self.center = np.asarray(center, dtype=float)
        self._center = tuple(self.center.tolist())
        self.domain = (0.0, 2.0 * np.pi)


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
    #: columns() works elementwise on a batch of parameters and of curve sizes (:mod:`contouring_ros.core.batch`)
    batchable = True
    formula = staticmethod(_parabola)

    def __init__(self, a: float, h: float):
        self.a = float(a)
        self.h = float(h)
        self.domain = (-self.a, self.a)

    @property
    def parameters(self) -> tuple:
        return (self.h,)

    def columns(self, t) -> list:
        return list(_parabola(t, self.parameters))


class Line(Curve):
    """Straight line from ``start`` to ``end`` parametrised by arc length theta in [0, L]."""

    #: columns() works elementwise on a batch of parameters and of curve sizes (:mod:`contouring_ros.core.batch`)
    batchable = True

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


class Circle(PlanarLoop):
    """Circle R = c + r [cos theta, sin theta], theta in [0, 2 pi), counter-clockwise."""

    #: columns() works elementwise on a batch of parameters and of curve sizes (:mod:`contouring_ros.core.batch`)
    batchable = True
    formula = staticmethod(_circle)

    def __init__(self, radius: float, center=(0.0, 0.0)):
        self.radius = float(radius)
        if self.radius <= 0.0:
            raise ValueError("circle radius must be positive")
        super().__init__(center)

    @property
    def parameters(self) -> tuple:
        return (self.radius, *self._center)

    def columns(self, t) -> list:
        return list(_circle(t, self.parameters))


class Ellipse(PlanarLoop):
    """Ellipse R = c + [a cos theta, b sin theta], theta in [0, 2 pi), counter-clockwise.

    Paper 003's XY-stage ellipse x = 0.03 (1 - cos wt), y = 0.01 sin wt is a = 0.03, b = 0.01,
    center (0.03, 0) with theta = w t + pi (the start point (0, 0) is theta = pi).
    """

    #: columns() works elementwise on a batch of parameters and of curve sizes (:mod:`contouring_ros.core.batch`)
    batchable = True
    formula = staticmethod(_ellipse)

    def __init__(self, a: float, b: float, center=(0.0, 0.0)):
        self.a, self.b = float(a), float(b)
        if self.a <= 0.0 or self.b <= 0.0:
            raise ValueError("ellipse semi-axes a and b must be positive")
        super().__init__(center)

    @property
    def parameters(self) -> tuple:
        return (self.a, self.b, *self._center)

    def columns(self, t) -> list:
        return list(_ellipse(t, self.parameters))


class FigureEight(PlanarLoop):
    """Figure-8 of paper 003, section IV-B: R = c + [a (1 - cos theta), b sin 2 theta], theta in [0, 2 pi)."""

    #: columns() works elementwise on a batch of parameters and of curve sizes (:mod:`contouring_ros.core.batch`)
    batchable = True
    formula = staticmethod(_figure_eight)

    def __init__(self, a: float, b: float, center=(0.0, 0.0)):
        self.a, self.b = float(a), float(b)
        if self.a <= 0.0 or self.b <= 0.0:
            raise ValueError("figure-8 sizes a and b must be positive")
        super().__init__(center)

    @property
    def parameters(self) -> tuple:
        return (self.a, self.b, *self._center)

    def columns(self, t) -> list:
        return list(_figure_eight(t, self.parameters))


class Helix(Curve):
    """Elliptical helix R = [a cos(w theta), b sin(w theta), c theta], theta in [0, length] (paper 003 eq. 26).

    With theta the time in seconds this is the paper's reference x = a cos wt, y = b sin wt, z = ct.
    """

    #: columns() works elementwise on a batch of parameters and of curve sizes (:mod:`contouring_ros.core.batch`)
    batchable = True
    formula = staticmethod(_helix)

    dimension = 3

    def __init__(self, a: float, b: float, c: float, omega: float, length: float):
        self.a, self.b, self.c, self.omega = float(a), float(b), float(c), float(omega)
        if self.a <= 0.0 or self.b <= 0.0 or self.omega == 0.0 or length <= 0.0:
            raise ValueError("helix a, b and length must be positive and omega non-zero")
        self.domain = (0.0, float(length))

    @property
    def parameters(self) -> tuple:
        return (self.a, self.b, self.c, self.omega)

    def columns(self, t) -> list:
        return list(_helix(t, self.parameters))


class Saddle(Curve):
    """Saddle curve of paper 004 eq. 27: R = [a cos(w theta), b sin(w theta), h cos(2 w theta)],
    theta in [0, 2 pi / w) (closed; with w = 2 pi, theta is the paper's time in seconds)."""

    #: columns() works elementwise on a batch of parameters and of curve sizes (:mod:`contouring_ros.core.batch`)
    batchable = True
    formula = staticmethod(_saddle)

    dimension = 3
    closed = True

    def __init__(self, a: float, b: float, h: float, omega: float = 2.0 * np.pi):
        self.a, self.b, self.h, self.omega = float(a), float(b), float(h), float(omega)
        if self.a <= 0.0 or self.b <= 0.0 or self.omega <= 0.0:
            raise ValueError("saddle a, b and omega must be positive")
        self.domain = (0.0, 2.0 * np.pi / self.omega)

    @property
    def parameters(self) -> tuple:
        return (self.a, self.b, self.h, self.omega)

    def columns(self, t) -> list:
        return list(_saddle(t, self.parameters))


class Butterfly(PlanarLoop):
    """Fay's butterfly without its slowly varying term, scaled: R = scale r(u) [sin u, cos u] with
    r(u) = exp(cos u) - 2 cos 4u, u in [0, 2 pi) (closed). The large- and varying-curvature test contour of
    the contouring literature that paper 002 runs (its own parametrisation is lost from the text)."""

    #: columns() works elementwise on a batch of parameters and of curve sizes (:mod:`contouring_ros.core.batch`)
    batchable = True
    formula = staticmethod(_butterfly)

    def __init__(self, scale: float, center=(0.0, 0.0)):
        self.scale = float(scale)
        if self.scale <= 0.0:
            raise ValueError("butterfly scale must be positive")
        super().__init__(center)

    @property
    def parameters(self) -> tuple:
        return (self.scale, *self._center)

    def columns(self, u) -> list:
        return list(_butterfly(u, self.parameters))


class SplineCurve(Curve):
    """Cubic B-spline interpolating the given points, parametrised by cumulative chord length [m] (a close
    stand-in for arc length); ``closed`` makes it periodic through the first point again. Derivatives up to
    the third are the spline's own (scipy.interpolate.make_interp_spline), exact for the piecewise cubic.

    Parameters
    ----------
    points : array_like, shape (m, n)
        At least 4 points (2-D or 3-D); consecutive points must differ.
    closed : bool
        Periodic spline (the last point is joined back to the first).
    """

    #: columns() works on a batch of parameters when every experiment of the batch has the same spline
    #: (:mod:`contouring_ros.core.batch`)
    batchable = True
    batch_shared = ("_splines",)

    def __init__(self, points, closed: bool = False):
        from scipy.interpolate import make_interp_spline
        points = np.asarray(points, dtype=float)
        if points.ndim != 2 or points.shape[0] < 4 or points.shape[1] not in (2, 3):
            raise ValueError("a spline needs at least 4 points of 2 or 3 coordinates")
        if closed and np.any(points[0] != points[-1]):
            points = np.vstack([points, points[:1]])
        chords = np.linalg.norm(np.diff(points, axis=0), axis=1)
        if np.any(chords <= 0.0):
            raise ValueError("consecutive spline points must differ")
        knots = np.concatenate([[0.0], np.cumsum(chords)])
        self.dimension = points.shape[1]
        self.closed = bool(closed)
        self.domain = (0.0, float(knots[-1]))
        spline = make_interp_spline(knots, points, k=3, bc_type="periodic" if closed else "not-a-knot")
        self._splines = [spline] + [spline.derivative(j) for j in (1, 2, 3)]

    def columns(self, t) -> list:
        if np.ndim(t) == 0:
            return [tuple(float(v) for v in s(float(t))) for s in self._splines]
        values = [s(t) for s in self._splines]
        return [tuple(v[..., i] for i in range(self.dimension)) for v in values]


#: m: a tool path longer than this is refused (a unit slip: G1 X50 written for millimetres is 50 m)
MAX_PATH_LENGTH = 10.0


class ToolPath(Curve):
    """A CNC tool path of straight lines and circular or helical arcs (G01 / G02 / G03), parametrised by arc
    length [m] from ``start``.

    Inline form (``ToolPath(start, moves)``, planar): each move is a string: ``"G1 X Y"`` a line to (X, Y);
    ``"G2 X Y I J"`` (clockwise) or ``"G3 X Y I J"`` (counter-clockwise) an arc to (X, Y) about the centre
    start + (I, J); coordinates in metres. The end point of an arc must lie on its circle (to 1 um).
    :meth:`from_program` builds one from a part program (:mod:`contouring_ros.core.gcode`, 2 or 3 axes),
    optionally blending line-line corners within a tolerance. Derivatives are analytic within each move; the
    curvature jumps where moves meet, as on a machine. ``blocks`` lists the stretches between block
    boundaries (:class:`PathBlock`) for feed planning and ``segments`` what each evaluates, both held as rows
    of arrays (:mod:`contouring_ros.core.path_tables`: a StretchTable and a SegmentTable).
    """

    #: columns() works on a batch of parameters when every experiment of the batch has the same path
    #: (:mod:`contouring_ros.core.batch`)
    batchable = True
    batch_shared = ("segments", "blocks", "program")
    batch_kept = ("_last",)           # the scalar path's last segment, a cache

    dimension = 2
    dwell = 0.0            # [s] G4 before the first motion

    def __init__(self, start, moves):
        position = np.asarray(start, dtype=float)
        if position.shape != (2,):
            raise ValueError("a tool path starts at a planar point [x, y]")
        self.segments = []            # (kind, start, end or centre, radius, start angle, direction, length)
        lengths = []
        for number, move in enumerate(moves, start=1):
            words = move.replace(",", " ").split()
            code = words[0].upper() if words else ""
            try:
                values = {w[0].upper(): float(w[1:]) for w in words[1:]}
            except ValueError:
                raise ValueError(f"move {number} {move!r}: expected words like X0.05") from None
            if not all(math.isfinite(v) and abs(v) <= 1e6 for v in values.values()):
                raise ValueError(f"move {number} {move!r}: every number must be finite and at most 1e+06 m in size")
            allowed = "XY" if code in ("G1", "G01") else "XYIJ"
            extra = [w for w in words[1:] if w[0].upper() not in allowed]
            if extra and code in ("G1", "G01", "G2", "G02", "G3", "G03"):
                raise ValueError(f"move {number} {move!r}: {extra[0]} is not read in inline moves (planar, metres: "
                                 f"{' '.join(allowed)}); a part program (curve type gcode) takes F, Z, K, R ...")
            if code in ("G1", "G01"):
                end = np.array([values.get("X", position[0]), values.get("Y", position[1])])
                length = float(np.linalg.norm(end - position))
                if length <= 0.0:
                    raise ValueError(f"move {number} {move!r}: a line of zero length")
                self.segments.append(("line", position, (end - position) / length, 0.0, 0.0, 0.0))
            elif code in ("G2", "G02", "G3", "G03"):
                if "I" not in values or "J" not in values:
                    raise ValueError(f"move {number} {move!r}: an arc needs its centre offset I and J")
                end = np.array([values.get("X", position[0]), values.get("Y", position[1])])
                centre = position + np.array([values["I"], values["J"]])
                radius = float(np.linalg.norm(position - centre))
                if radius <= 0.0 or abs(np.linalg.norm(end - centre) - radius) > 1e-6:
                    raise ValueError(f"move {number} {move!r}: the end point is not on the arc's circle")
                direction = 1.0 if code in ("G3", "G03") else -1.0
                a0 = float(np.arctan2(*(position - centre)[::-1]))
                a1 = float(np.arctan2(*(end - centre)[::-1]))
                sweep = (direction * (a1 - a0)) % (2 * np.pi) or 2 * np.pi
                length = radius * sweep
                self.segments.append(("arc", centre, None, radius, a0, direction))
            else:
                raise ValueError(f"move {number} {move!r}: expected G1, G2 or G3")
            lengths.append(length)
            position = end
            if sum(lengths) > MAX_PATH_LENGTH:
                raise ValueError(f"move {number} {move!r}: the path is over {MAX_PATH_LENGTH:g} m long; inline "
                                 "moves are in metres (G1 X50 is 50 m: write X0.05, or use a part program with "
                                 "G21 for millimetres)")
        if not self.segments:
            raise ValueError("a tool path needs at least one move")
        self._finish((segment, length, "arc" if segment[0] == "arc" else "line", None, n, 0.0, 0.0)
                     for n, (segment, length) in enumerate(zip(self.segments, lengths), start=1))

    @classmethod
    def from_program(cls, program, blend_tolerance: float = 0.0) -> "ToolPath":
        """The tool path of a part program (:class:`contouring_ros.core.gcode.Program`).

        Each block's path tolerance is the program's (G64 P, G61, G9: ``Block.tolerance``), else
        ``blend_tolerance``. A tolerance P > 0 rounds the corner between two G1 lines at the block's end by
        the circular arc tangent to both whose distance from the corner is at most P: for a turn angle phi
        that arc has radius r = P / (1 / cos(phi / 2) - 1) and meets the lines t = r tan(phi / 2) from the
        corner (the arc blend of LinuxCNC's trajectory planner, tp.c); t is capped at 0.45 of each line's
        programmed length, which only lowers the deviation, so blending works for lines of any length. Other
        corners keep P as their junction deviation for the feed planner; 0 keeps the corner exact (the feed
        planner stops there, as G61).
        """
        self = cls.__new__(cls)
        self.dimension = program.dimension
        self.dwell = program.dwell
        self._finish(item[:7] for item in _blend(_program_items(program.blocks, program.dimension, blend_tolerance)))
        total = self.domain[1]
        if not math.isfinite(total) or total > MAX_PATH_LENGTH:
            raise ValueError(f"the path is {total:.4g} m long (at most {MAX_PATH_LENGTH:g} m): check the units "
                             "(G1 X50 is 50 mm under G21, the default, and 50 inch = 1.27 m under G20)")
        return self

    @staticmethod
    def stream(blocks, dimension: int, blend_tolerance: float = 0.0):
        """The tool path of a stream of part-program blocks (:class:`contouring_ros.core.gcode.Block`, any
        iterable), as :meth:`from_program` makes it, one stretch at a time: each a (segment, :class:`PathBlock`)
        pair, the segment what :func:`segment_columns` evaluates; a run of G1 lines
        (:class:`~contouring_ros.core.gcode.LineRun`, read with ``ProgramReader.blocks(runs=True)``) as a
        :class:`~contouring_ros.core.line_runs.StretchChunk` of its stretches (the same numbers). At most two
        blocks or a run and a block are held (a corner's blend needs the block after it), so a program of any
        length streams in constant memory; the total length is not capped (:data:`MAX_PATH_LENGTH` guards a
        whole program's units)."""
        start = 0.0
        for item in _blend(_program_items(blocks, dimension, blend_tolerance)):
            if item.__class__ is StretchChunk:                  # a run of lines and their blends as arrays
                start = item.place(start)
                yield item
                continue
            segment, length, kind, feed, line, deviation, dwell, _ = item
            plain = (segment[1], segment[2]) if segment[0] == "line" else (segment[1], *segment[2])
            yield (segment, plain), _path_block(segment, plain, dimension, start, length, kind, feed, line,
                                                deviation, dwell)
            start += length

    def _finish(self, stretches) -> None:
        """Hold the path's (segment, length, kind, feed, line, deviation, dwell) stretches as rows of tables
        (:mod:`contouring_ros.core.path_tables`), one at a time: no object per stretch is kept."""
        n = self.dimension
        segments, blocks = SegmentTable.build(n), StretchTable.build(n)
        for segment, length, kind, feed, line, deviation, dwell in stretches:
            segments.add(SegmentTable.row(segment, n))
            blocks.add(StretchTable.row(kind, length, feed, *_stretch_shape(segment, _plain(segment), n, length),
                                        deviation, dwell), line)
        self.segments, self.blocks = segments.table(SegmentTable), blocks.table(StretchTable)
        self._starts = self.blocks.starts
        self.domain = (0.0, float(self._starts[-1]))
        self.closed = False
        self._last = (-1, None)             # the scalar path's last segment: (index, SegmentTable.plain's pair)

    def _segment(self, i: int, u: float) -> list:
        """[R, dR, d2R, d3R] at distance u into segment i, as tuples of floats (the estimators' scalar path)."""
        last, pair = self._last
        if last != i:
            pair = self.segments.plain(i)
            self._last = (i, pair)
        return segment_columns(pair[0], pair[1], self.dimension, u)

    def _one(self, s: float) -> list:
        i = min(max(int(np.searchsorted(self._starts, s, side="right")) - 1, 0), len(self.segments) - 1)
        return self._segment(i, s - float(self._starts[i]))

    def columns(self, t) -> list:
        if np.ndim(t) == 0:
            return [tuple(float(v) for v in row) for row in self._one(float(t))]
        shape, flat = np.shape(t), np.ravel(np.asarray(t, dtype=float))
        index = np.minimum(np.maximum(np.searchsorted(self._starts, flat, side="right") - 1, 0), len(self.segments) - 1)
        first = int(index[0])
        if (index == first).all():       # all on one segment (a batch's members mostly are): no masks
            out = self._segment_array(first, flat - self._starts[first])
        else:
            out = self._segments_array(index, flat - self._starts[index])
        return [tuple(out[j][:, c].reshape(shape) for c in range(self.dimension)) for j in range(4)]

    def _segments_array(self, index: np.ndarray, u: np.ndarray) -> list:
        """:meth:`_segment_array` of each distance ``u`` into its own segment ``index``, the segments of a
        kind at once (elementwise the same arithmetic): 4 arrays of shape (len(u), dim)."""
        table = self.segments
        out = [np.zeros((u.size, self.dimension)) for _ in range(4)]
        kinds = table.kind[index]
        for code, kind in enumerate(SEGMENT_KINDS):
            inside = np.flatnonzero(kinds == code)
            if not inside.size:
                continue
            rows, x = index[inside], u[inside]
            origin = table.vector(0)[rows]
            if kind == "line":
                direction = table.vector(1)[rows]
                out[0][inside] = origin + x[:, None] * direction
                out[1][inside] = direction
            elif kind == "helix":
                e1, e2, w = table.vector(1)[rows], table.vector(2)[rows], table.vector(3)[rows]
                radius, rho, turn = (table.number(name)[rows, None] for name in ("radius", "rho", "turn"))
                a = table.number("a0")[rows, None] + turn * x[:, None] / rho
                c, si = _cos(a), _sin(a)
                k1, k2, k3 = radius * turn / rho, radius / rho**2, radius * turn / rho**3
                out[0][inside] = origin + radius * (c * e1 + si * e2) + w * x[:, None]
                out[1][inside] = k1 * (c * e2 - si * e1) + w
                out[2][inside] = -k2 * (c * e1 + si * e2)
                out[3][inside] = k3 * (si * e1 - c * e2)
            else:
                radius, turn = table.number("radius")[rows], table.number("turn")[rows]
                a = table.number("a0")[rows] + turn * x / radius
                c, si = _cos(a), _sin(a)
                out[0][inside] = np.column_stack([origin[:, 0] + radius * c, origin[:, 1] + radius * si])
                out[1][inside] = np.column_stack([-turn * si, turn * c])
                out[2][inside] = np.column_stack([-c / radius, -si / radius])
                out[3][inside] = np.column_stack([turn * si / radius**2, -turn * c / radius**2])
        return out

    def _segment_array(self, i: int, u: np.ndarray) -> list:
        """:meth:`_segment` for an array of distances ``u`` into segment i: 4 arrays of shape (len(u), dim)."""
        table = self.segments
        kind = SEGMENT_KINDS[table.kind[i]]
        origin = table.vector(0)[i]
        radius, a0, turn, rho = (float(table.number(name)[i]) for name in ("radius", "a0", "turn", "rho"))
        u = u[:, None]
        if kind == "line":
            direction = table.vector(1)[i]
            zero = np.zeros((u.shape[0], self.dimension))
            return [origin + u * direction, np.broadcast_to(direction, zero.shape), zero, zero]
        if kind == "helix":
            e1, e2, w = table.vector(1)[i], table.vector(2)[i], table.vector(3)[i]
            a = a0 + turn * u / rho
            c, si = _cos(a), _sin(a)
            k1, k2, k3 = radius * turn / rho, radius / rho**2, radius * turn / rho**3
            return [origin + radius * (c * e1 + si * e2) + w * u, k1 * (c * e2 - si * e1) + w,
                    -k2 * (c * e1 + si * e2), k3 * (si * e1 - c * e2)]
        a = a0 + turn * u[:, 0] / radius
        c, si = _cos(a), _sin(a)
        return [np.column_stack([origin[0] + radius * c, origin[1] + radius * si]),
                np.column_stack([-turn * si, turn * c]), np.column_stack([-c / radius, -si / radius]),
                np.column_stack([turn * si / radius**2, -turn * c / radius**2])]


def segment_columns(segment, plain, n: int, u: float) -> list:
    """[R, dR, d2R, d3R] at distance u into a tool path's segment (a line, a helix or a planar arc of an inline
    path; ``plain`` its vectors as tuples of floats, :func:`_plain`) of dimension n, as tuples of floats."""
    kind, origin, direction, radius, a0, turn = segment
    if kind == "line":
        o, d = plain
        zero = (0.0,) * n
        return [tuple([ok + u * dk for ok, dk in zip(o, d)]), d, zero, zero]
    if kind == "helix":
        o, e1, e2, w, rho = plain
        c, si = _helix_angle(plain, a0, turn, u)
        k2, k3 = radius / rho**2, radius * turn / rho**3
        return [tuple([ok + radius * (c * x + si * y) + wk * u for ok, x, y, wk in zip(o, e1, e2, w)]),
                _helix_tangent(plain, radius, turn, c, si),
                tuple([-k2 * (c * x + si * y) for x, y in zip(e1, e2)]),
                tuple([k3 * (si * x - c * y) for x, y in zip(e1, e2)])]
    a = a0 + turn * u / radius
    c, si = _cos(a), _sin(a)
    return [(origin[0] + radius * c, origin[1] + radius * si), (-turn * si, turn * c),
            (-c / radius, -si / radius), (turn * si / radius**2, -turn * c / radius**2)]


def _helix_angle(plain, a0: float, turn: float, u: float) -> tuple:
    """(cos, sin) of a helix segment's angle at distance u into it."""
    a = a0 + turn * u / plain[4]
    return math.cos(a), math.sin(a)


def _helix_tangent(plain, radius: float, turn: float, c: float, si: float) -> tuple:
    """dR of a helix segment where its angle's cosine and sine are ``c`` and ``si`` (:func:`_helix_angle`)."""
    _, e1, e2, w, rho = plain
    k1 = radius * turn / rho
    return tuple([k1 * (c * y - si * x) + wk for x, y, wk in zip(e1, e2, w)])


def _plain(segment):
    """A segment's vectors as tuples of floats (the scalar path of :func:`segment_columns`): those of a
    program's segment (tuples already) as they are."""
    kind, origin, direction, *_ = segment
    if kind == "line":
        return _floats(origin), _floats(direction)
    if kind == "helix":
        return (_floats(origin), *(_floats(v) for v in direction[:3]), float(direction[3]))
    return None


def _floats(vector) -> tuple:
    """A vector as a tuple of floats (a tuple of floats as it is)."""
    if type(vector) is tuple and all(type(x) is float for x in vector):
        return vector
    return tuple(np.asarray(vector, dtype=float).tolist())


def _path_block(segment, plain, n, start, length, kind, feed, line, deviation, dwell) -> PathBlock:
    """The :class:`PathBlock` of one segment beginning at arc length ``start``."""
    tangent_in, tangent_out, curvature = _stretch_shape(segment, plain, n, length)
    return PathBlock(kind, float(start), float(length), feed, line, np.array(tangent_in), np.array(tangent_out),
                     curvature, float(deviation), float(dwell))


def _stretch_shape(segment, plain, n, length) -> tuple:
    """(unit tangent at its start, at its end, curvature) of a segment of ``length``, as floats."""
    if segment[0] == "line":                 # one direction: its tangent at both ends
        tangent = _unit(plain[1])
        return tangent, tangent, 0.0
    if segment[0] == "helix":               # the two tangents and |d2R| (a helix's is the same everywhere)
        _, _, _, radius, a0, turn = segment
        c, si = _helix_angle(plain, a0, turn, 0.0)
        k2 = radius / plain[4]**2
        curvature = _norm([k2 * (c * x + si * y) for x, y in zip(plain[1], plain[2])])
        return (_unit(_helix_tangent(plain, radius, turn, c, si)),
                _unit(_helix_tangent(plain, radius, turn, *_helix_angle(plain, a0, turn, float(length)))), curvature)
    begin, end = segment_columns(segment, plain, n, 0.0), segment_columns(segment, plain, n, float(length))
    return _unit(begin[1]), _unit(end[1]), _norm(begin[2])          # a planar arc of an inline path


def _norm(vector) -> float:
    """The length of a vector of floats, as np.linalg.norm computes it (the square root of the sum of the
    squares, in order) without numpy's overhead on 2 or 3 elements."""
    total = 0.0
    for x in vector:
        total += x * x
    return math.sqrt(total)


def _unit(vector) -> tuple:
    length = _norm(vector)
    return tuple([x / length for x in vector])


def _program_items(blocks, d: int, blend_tolerance: float):
    """Each part-program block's segment as :func:`_blend` takes it: [segment, length, kind, feed, line,
    tolerance, dwell] (a generator; the segment's vectors as tuples of floats); a run of lines blended at its
    corners as its :class:`~contouring_ros.core.line_runs.LineItems` (its blocks one at a time where it does
    not blend, or a number is not finite)."""
    for block in blocks:
        tolerance = blend_tolerance if block.tolerance is None else block.tolerance
        if block.kind == "run":
            items = LineItems(block, d, tolerance) if tolerance > 0.0 else None
            if items is not None and items.finite:
                yield items
            else:
                yield from _program_items(block.blocks(), d, blend_tolerance)
            continue
        if block.kind in ("line", "rapid"):
            start, end = block.start[:d].tolist(), block.end[:d].tolist()
            chord = [e - s for s, e in zip(start, end)]
            length = _norm(chord)
            item = [("line", tuple(start), tuple([x / length for x in chord]), 0.0, 0.0, 0.0), length, block.kind,
                    block.feed, block.line, tolerance, block.dwell]
        else:
            first, second, normal = block.plane
            centre = block.centre
            a = np.array([block.start[first] - centre[first], block.start[second] - centre[second]])
            b = np.array([block.end[first] - centre[first], block.end[second] - centre[second]])
            radius = float(np.linalg.norm(a))
            turn = -1.0 if block.clockwise else 1.0
            a0, a1 = math.atan2(a[1], a[0]), math.atan2(b[1], b[0])
            sweep = (turn * (a1 - a0)) % (2 * np.pi) or 2 * np.pi
            e1, e2, w = np.zeros(3), np.zeros(3), np.zeros(3)
            e1[first], e1[second] = 1.0, 0.0
            e2[first], e2[second] = 0.0, 1.0
            rise = float(block.end[normal] - block.start[normal])
            rho = math.hypot(radius, rise / sweep)
            length = rho * sweep
            w[normal] = rise / length
            base = centre.copy()
            base[normal] = block.start[normal]
            item = [("helix", _floats(base[:d]), (_floats(e1[:d]), _floats(e2[:d]), _floats(w[:d]), rho), radius, a0,
                     turn), length, "arc", block.feed, block.line, tolerance, block.dwell]
        # every derived length and radius finite (a NaN passes the length guard)
        _, origin, direction, radius, *_ = item[0]
        vectors = direction[:3] if item[0][0] == "helix" else (direction,)
        if not all(math.isfinite(v) for v in (item[1], radius, *origin, *(x for v in vectors for x in v))):
            raise ValueError(f"line {item[4]}: the move's length or radius is not a finite number "
                             "(coordinates or offsets too large)")
        yield item


def _blend(items):
    """Insert a tangent arc at each corner between two G1 lines whose first has a tolerance and no dwell
    (see :meth:`ToolPath.from_program`); a generator holding one item back (its end is cut by the corner's
    blend). Vectors are tuples of floats, each component computed as numpy would compute it elementwise. A
    run's :class:`~contouring_ros.core.line_runs.LineItems` comes out as a
    :class:`~contouring_ros.core.line_runs.StretchChunk` of its lines and blends but the last line, held."""
    previous = None
    for item in items:
        run = item if item.__class__ is LineItems else None
        item = run.item(0) if run is not None else list(item) + [item[1]]
        if previous is not None:
            arc = _corner_blend(previous, item)
            yield previous
            if arc is not None:
                yield arc
        previous = item
        if run is not None and len(run) > 1:
            chunk, previous = run.blend(previous)
            yield chunk
    if previous is not None:
        yield previous


def _corner_blend(previous: list, item: list):
    """The blend arc item at the corner where ``previous`` meets ``item`` (None: none), both cut back by it."""
    (_, _, u1, *_), length0 = previous[0], previous[1]
    (_, p1, u2, *_), length1 = item[0], item[1]
    tolerance = previous[5]
    if not (previous[2] == "line" and item[2] == "line" and tolerance > 0.0 and not previous[6]):
        return None
    difference = tuple([b - a for a, b in zip(u1, u2)])
    chord = _norm(difference)
    phi = 2.0 * math.atan2(chord, _norm([a + b for a, b in zip(u1, u2)]))     # the turn, at any angle
    if not 1e-9 < phi < math.pi - 1e-6:
        return None
    radius, cut = blend_radius(phi, tolerance, 0.45 * min(previous[7], item[7]))   # of the programmed lengths
    corner = p1
    cosine = math.cos(phi / 2.0)
    centre = tuple([c + x / chord * radius / cosine for c, x in zip(corner, difference)])
    e1 = tuple([(c - u * cut - m) / radius for c, u, m in zip(corner, u1, centre)])
    previous[1] = length0 - cut
    feeds = [f for f in (previous[3], item[3]) if f is not None]
    item[0] = ("line", tuple([c + u * cut for c, u in zip(corner, u2)]), u2, 0.0, 0.0, 0.0)
    item[1] = length1 - cut
    return [("helix", centre, (e1, u1, (0.0,) * len(u1), radius), radius, 0.0, 1.0), radius * phi,
            "blend", min(feeds) if feeds else None, item[4], tolerance, 0.0, radius * phi]
