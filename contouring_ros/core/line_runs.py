"""Runs of plain G1 lines as arrays: what a long CAM program mostly is (chords of microns under G64 P), read,
blended and made tool-path stretches a run at a time instead of a block at a time.

- :class:`~contouring_ros.core.gcode.LineRun` (the reader's, here for the arithmetic on it): consecutive G1
  blocks of one feed and path tolerance, their points as one array (read by
  :meth:`~contouring_ros.core.gcode.ProgramReader.blocks` with ``runs=True``); ``LineRun.blocks`` gives the
  :class:`~contouring_ros.core.gcode.Block` objects the general reader makes of the same lines.
- :class:`LineItems`: a run's lines as the tool path takes them (origin, unit direction, length), and
  :meth:`LineItems.blend`: the blend arcs at its corners (:meth:`~contouring_ros.core.curves.ToolPath.
  from_program`'s formula) for all corners at once.
- :class:`StretchChunk`: the stretches that makes (the lines, cut back by the arcs, and the arcs), each
  row's unit tangents and curvature as :func:`~contouring_ros.core.curves._stretch_shape` gives them, and
  row k as the ((segment, plain), :class:`~contouring_ros.core.path_tables.PathBlock`) pair the scalar
  path yields (:meth:`StretchChunk.pair`).

Every number is the scalar path's double bit for bit (tested): the arithmetic is numpy's elementwise, in
the scalar path's order; sines, cosines, arc tangents and powers are the math module's, element by element
(numpy's SIMD versions may differ in the last bit).
"""
from __future__ import annotations

import math

import numpy as np

from .gcode import LineRun
from .path_tables import PathBlock

__all__ = ["LineItems", "StretchChunk", "blend_radius"]


def blend_radius(phi: float, tolerance: float, limit: float) -> tuple:
    """(radius, cut) of the arc blending a turn ``phi`` between two lines within ``tolerance`` of the corner,
    cut back to ``limit`` along each line (:meth:`~contouring_ros.core.curves.ToolPath.from_program`):
    r = P cos(phi / 2) / (1 - cos(phi / 2)), 1 - cos(half) written 2 sin^2(half / 2) / cos(half) (exact for
    tiny turns), which meets the lines r tan(phi / 2) from the corner."""
    half = phi / 2.0
    radius = tolerance * math.cos(half) / (2.0 * math.sin(half / 2.0) ** 2)
    cut = radius * math.tan(half)
    if cut > limit:
        cut, radius = limit, limit / math.tan(half)
    return radius, cut


def _norms(vectors: np.ndarray) -> np.ndarray:
    """Each row's length, as :func:`~contouring_ros.core.curves._norm` sums the squares (in order)."""
    total = vectors[:, 0] * vectors[:, 0]
    for k in range(1, vectors.shape[1]):
        total = total + vectors[:, k] * vectors[:, k]
    return np.sqrt(total)


def _units(vectors: np.ndarray) -> np.ndarray:
    return vectors / _norms(vectors)[:, None]


class LineItems:
    """A :class:`LineRun`'s lines on ``d`` axes as the tool path takes them: ``origins`` (n, d), unit
    ``directions`` (n, d) and ``lengths`` (n,) (the chord over its length, as the scalar path divides), the
    run's ``feed``, ``lines`` and path ``tolerance`` (resolved: > 0)."""

    def __init__(self, run: LineRun, d: int, tolerance: float):
        points = run.points[:, :d]
        chords = points[1:] - points[:-1]
        self.lengths = _norms(chords)
        self.origins, self.directions = points[:-1], chords / self.lengths[:, None]
        self.feed, self.lines, self.tolerance = run.feed, run.lines, tolerance
        self.finite = bool(np.isfinite(self.lengths).all() and np.isfinite(self.directions).all()
                           and np.isfinite(self.origins).all())

    def __len__(self) -> int:
        return len(self.lengths)

    def item(self, i: int) -> list:
        """Line i as :func:`~contouring_ros.core.curves._blend` holds an item (its programmed length last)."""
        length = float(self.lengths[i])
        return [("line", tuple(self.origins[i].tolist()), tuple(self.directions[i].tolist()), 0.0, 0.0, 0.0),
                length, "line", self.feed, int(self.lines[i]), self.tolerance, 0.0, length]

    def blend(self, first: list) -> tuple:
        """(the :class:`StretchChunk` of lines 0 .. n - 2 and the blend arcs at the corners after them, line
        n - 1 as a held item): the corner blends of :func:`~contouring_ros.core.curves._blend` at corners 0 ..
        n - 2, line 0 given as ``first`` (the item of :meth:`item` as the corner before it left it: cut at its
        start)."""
        u, lengths, tolerance = self.directions, self.lengths, self.tolerance
        u1, u2 = u[:-1], u[1:]
        difference = u2 - u1
        chord = _norms(difference)
        phi = 2.0 * np.array(list(map(math.atan2, chord.tolist(), _norms(u1 + u2).tolist())))
        blended = np.flatnonzero((1e-9 < phi) & (phi < math.pi - 1e-6))
        limits = 0.45 * np.minimum(lengths[:-1], lengths[1:])
        radius, cut = np.zeros(len(phi)), np.zeros(len(phi))
        for j, p, limit in zip(blended.tolist(), phi[blended].tolist(), limits[blended].tolist()):
            radius[j], cut[j] = blend_radius(p, tolerance, limit)
        cosine = np.array([math.cos(p / 2.0) for p in phi[blended].tolist()])
        r, c = radius[blended], cut[blended]
        corner = self.origins[1:][blended]
        centre = corner + difference[blended] / chord[blended, None] * r[:, None] / cosine[:, None]
        e1 = (corner - u1[blended] * c[:, None] - centre) / r[:, None]
        # each line cut at its start by the corner before it, then at its end by the one after it
        current = lengths.copy()
        current[0] = first[1]
        current[1:][blended] = lengths[1:][blended] - c
        origins = self.origins.copy()
        origins[0] = first[0][1]
        origins[1:][blended] = corner + u2[blended] * c[:, None]
        cut_lengths = current[:-1].copy()
        cut_lengths[blended] = current[:-1][blended] - c
        last = list(self.item(len(self) - 1))
        last[0] = ("line", tuple(origins[-1].tolist()), last[0][2], 0.0, 0.0, 0.0)
        last[1] = float(current[-1])
        return StretchChunk(self, origins[:-1], cut_lengths, blended, centre, e1, r, r * phi[blended]), last


class StretchChunk:
    """Consecutive stretches of a tool path as arrays: a run's lines 0 .. n - 2 (``origins``, their unit
    directions and ``lengths`` after the blends' cuts) and the blend arc after each line in ``blended``
    (its ``centre``, in-plane unit vectors e1 (``e1``) and e2 (the line's direction), ``radius`` and
    ``arc_lengths``), in path order. ``start`` [m]: where the first begins (set by the tool path's stream).

    Per row (``kind``: 0 a line, 1 an arc): ``lengths``, ``lines``, ``tangent_in``, ``tangent_out``,
    ``curvature``, ``starts`` (once ``start`` is set), ``feed``, ``deviation``."""

    def __init__(self, items: LineItems, origins, lengths, blended, centre, e1, radius, arc_lengths):
        n, d = len(lengths), origins.shape[1]
        directions = items.directions[:n]
        slot = np.arange(n) * 2
        rows = np.sort(np.concatenate([slot, slot[blended] + 1]))
        line_row = np.searchsorted(rows, slot)                 # where line i and arc j land among the rows
        arc_row = line_row[blended] + 1
        m = len(rows)
        self.size, self.dimension = m, d
        self.feed, self.deviation = items.feed, items.tolerance
        self.kind = np.zeros(m, dtype=np.int8)
        self.kind[arc_row] = 1
        self.lengths = np.empty(m)
        self.lengths[line_row], self.lengths[arc_row] = lengths, arc_lengths
        self.lines = np.empty(m, dtype=np.int64)
        self.lines[line_row], self.lines[arc_row] = items.lines[:n], items.lines[1:n + 1][blended]
        self.origin, self.vector1, self.vector2 = np.empty((m, d)), np.empty((m, d)), np.zeros((m, d))
        self.origin[line_row], self.origin[arc_row] = origins, centre
        self.vector1[line_row], self.vector1[arc_row] = directions, e1
        self.vector2[arc_row] = directions[blended]
        self.radius = np.zeros(m)
        self.radius[arc_row] = radius
        # unit tangents and curvature (curves._stretch_shape): a line's direction made unit again; an arc's
        # (a helix of a0 0, turn 1, rho its radius, no rise) from its angle at 0 and at its length
        self.tangent_in, self.tangent_out = np.empty((m, d)), np.empty((m, d))
        self.tangent_in[line_row] = self.tangent_out[line_row] = _units(directions)
        self.curvature = np.zeros(m)
        if len(radius):
            k1 = radius * 1.0 / radius
            k2 = np.array([r / r ** 2 for r in radius.tolist()])
            e2 = directions[blended]
            self.curvature[arc_row] = _norms(k2[:, None] * (1.0 * e1 + 0.0 * e2))
            self.tangent_in[arc_row] = _units(k1[:, None] * (1.0 * e2 - 0.0 * e1) + 0.0)
            angle = 0.0 + 1.0 * arc_lengths / radius
            c = np.array(list(map(math.cos, angle.tolist())))[:, None]
            s = np.array(list(map(math.sin, angle.tolist())))[:, None]
            self.tangent_out[arc_row] = _units(k1[:, None] * (c * e2 - s * e1) + 0.0)
        self.start, self.starts = 0.0, None

    def __len__(self) -> int:
        return self.size

    def place(self, start: float) -> float:
        """Begin the chunk at arc length ``start``: each row's start, summed in order as the scalar stream
        sums them; returns where the chunk ends."""
        sums = np.cumsum(np.concatenate([[start], self.lengths]))
        self.start, self.starts = start, sums[:-1]
        return float(sums[-1])

    def pair(self, k: int) -> tuple:
        """Row k as the scalar stream yields a stretch: ((segment, plain), PathBlock)."""
        origin, vector1 = tuple(self.origin[k].tolist()), tuple(self.vector1[k].tolist())
        line, length = int(self.lines[k]), float(self.lengths[k])
        if self.kind[k] == 0:
            segment, plain, kind = ("line", origin, vector1, 0.0, 0.0, 0.0), (origin, vector1), "line"
        else:
            radius, zero = float(self.radius[k]), (0.0,) * self.dimension
            e2 = tuple(self.vector2[k].tolist())
            segment = ("helix", origin, (vector1, e2, zero, radius), radius, 0.0, 1.0)
            plain, kind = (origin, vector1, e2, zero, radius), "blend"
        block = PathBlock(kind, float(self.starts[k]), length, self.feed, line, self.tangent_in[k].copy(),
                          self.tangent_out[k].copy(), float(self.curvature[k]), float(self.deviation), 0.0)
        return (segment, plain), block
