"""A tool path's segments and stretches held as arrays, one row each (a struct of arrays), read back one at a
time as the tuples the scalar path evaluates and the :class:`PathBlock` records the feed planner takes.

A chord of a long part program held as objects (a tuple per segment, a record with two tangent arrays per
stretch) costs about 1.6 kB; as rows of these tables it costs under 0.3 kB, so a program of a million
chords fits in memory with its plan. The numbers are the same doubles either way: a path evaluates bit for
bit as it did from the objects.
"""
from __future__ import annotations

import math
from array import array
from dataclasses import dataclass

import numpy as np

__all__ = ["PathBlock", "RowSequence", "SegmentTable", "StretchTable", "SEGMENT_KINDS", "STRETCH_KINDS"]

#: what a segment is: a straight line, a helix (a program's arc, helical or not, or a corner's blend arc) or a
#: planar arc of an inline path
SEGMENT_KINDS = ("line", "helix", "arc")

#: what a stretch is to the feed planner (:attr:`PathBlock.kind`)
STRETCH_KINDS = ("line", "rapid", "arc", "blend")


@dataclass(frozen=True, slots=True)
class PathBlock:
    """One stretch of a tool path between two block boundaries, as the feed planner sees it.

    Attributes
    ----------
    kind : str
        ``line``, ``rapid``, ``arc`` (G2 / G3, helical or not) or ``blend`` (an arc inserted at a corner).
    start : float
        Arc length [m] where it begins; ``length`` its length [m].
    feed : float or None
        Its programmed feed limit [m/s] (None: the schedule's feedrate; rapids: the schedule's rapid rate).
    line : int
        Source line (part program) or move number (inline moves).
    tangent_in, tangent_out : ndarray
        Unit tangents at its two ends.
    curvature : float
        Curvature [1/m] (0 on lines; r / (r^2 + p^2) on a helix of radius r and pitch p per radian).
    deviation : float
        How far [m] the path may leave the corner at its end (G64 P): 0 is an exact stop there (G61, G9).
    dwell : float
        [s] G4 dwell after it (the motion stops there first).
    """

    kind: str
    start: float
    length: float
    feed: float | None
    line: int
    tangent_in: np.ndarray
    tangent_out: np.ndarray
    curvature: float
    deviation: float = 0.0
    dwell: float = 0.0


class RowSequence:
    """A sequence whose item i is made from row i of a table on access (:meth:`row_item`): an index, a
    negative one or a slice (a list), and iteration in order."""

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self.row_item(j) for j in range(len(self))[i]]
        return self.row_item(range(len(self))[i])

    def __iter__(self):
        for i in range(len(self)):
            yield self.row_item(i)


class SegmentTable(RowSequence):
    """The segments of a tool path, one row each: what :func:`contouring_ros.core.curves.segment_columns`
    evaluates.

    A row holds the segment's origin (a line's start, an arc's centre, a helix's axis point), then two
    directions and a rise (a line's unit direction; a helix's in-plane unit vectors e1, e2 and its rise per
    unit length w), then rho (a helix's length per radian), the radius, the start angle and the turn (+1
    counter-clockwise, -1 clockwise). Item i is the segment as a tuple (kind, origin, direction, radius,
    start angle, turn), its vectors tuples of floats; :meth:`plain` gives the same with its vectors
    unpacked.
    """

    def __init__(self, dimension: int, kinds: np.ndarray, numbers: np.ndarray):
        self.dimension = dimension
        self._kind = kinds                  # index into SEGMENT_KINDS
        self._numbers = numbers             # (n, 4 dimension + 4)

    @classmethod
    def build(cls, dimension: int) -> "_Rows":
        """Rows to :meth:`_Rows.add` segments to, one at a time; ``.table(SegmentTable)`` ends them."""
        return _Rows(dimension, 4 * dimension + 4)

    @staticmethod
    def row(segment, dimension: int) -> tuple:
        """(kind code, the numbers of its row) of a segment tuple."""
        kind, origin, direction, radius, a0, turn = segment
        zero = (0.0,) * dimension
        if kind == "line":
            vectors = (origin, direction, zero, zero)
            rho = 0.0
        elif kind == "helix":
            *vectors, rho = direction
            vectors = (origin, *vectors)
        else:
            vectors, rho = (origin, zero, zero, zero), 0.0
        numbers = [float(x) for vector in vectors for x in vector] + [float(rho), float(radius), float(a0), float(turn)]
        return SEGMENT_KINDS.index(kind), numbers

    def __len__(self) -> int:
        return len(self._kind)

    def row_item(self, i: int) -> tuple:
        return self.plain(i)[0]

    def plain(self, i: int) -> tuple:
        """(segment tuple, its vectors as tuples of floats) of segment i: (origin, direction) of a line,
        (origin, e1, e2, w, rho) of a helix, None of a planar arc."""
        kind = SEGMENT_KINDS[self._kind[i]]
        row = self._numbers[i].tolist()
        d = self.dimension
        origin = tuple(row[:d])
        rho, radius, a0, turn = row[4 * d:]
        if kind == "line":
            direction = tuple(row[d:2 * d])
            return ("line", origin, direction, 0.0, 0.0, 0.0), (origin, direction)
        if kind == "helix":
            e1, e2, w = tuple(row[d:2 * d]), tuple(row[2 * d:3 * d]), tuple(row[3 * d:4 * d])
            return ("helix", origin, (e1, e2, w, rho), radius, a0, turn), (origin, e1, e2, w, rho)
        return ("arc", origin, None, radius, a0, turn), None

    # the columns as arrays, for the vectorised path (views of the rows)
    @property
    def kind(self) -> np.ndarray:
        """Each segment's kind, an index into :data:`SEGMENT_KINDS`."""
        return self._kind

    def vector(self, k: int) -> np.ndarray:
        """The k-th vector of every row (0 origin, 1 a line's direction or e1, 2 e2, 3 w): shape (n, d)."""
        d = self.dimension
        return self._numbers[:, k * d:(k + 1) * d]

    def number(self, name: str) -> np.ndarray:
        """One number of every row: ``rho``, ``radius``, ``a0`` or ``turn``."""
        return self._numbers[:, 4 * self.dimension + ("rho", "radius", "a0", "turn").index(name)]


class StretchTable(RowSequence):
    """The stretches of a tool path, one row each: item i is its :class:`PathBlock` (made on access), so a
    program of any length costs its rows, not its records; :meth:`column` gives one field of every row as an
    array."""

    def __init__(self, dimension: int, kinds: np.ndarray, lines: np.ndarray, numbers: np.ndarray):
        self.dimension = dimension
        self._kind = kinds                  # index into STRETCH_KINDS
        self._line = lines
        self._numbers = numbers             # (n, 2 dimension + 5): length, feed, tangents, curvature, deviation, dwell
        self.starts = np.concatenate([[0.0], np.cumsum(numbers[:, 0])])      # n + 1: where each begins, the end

    @classmethod
    def build(cls, dimension: int) -> "_Rows":
        return _Rows(dimension, 2 * dimension + 5, lines=True)

    @staticmethod
    def row(kind: str, length: float, feed, tangent_in, tangent_out, curvature: float, deviation: float,
            dwell: float) -> tuple:
        """(kind code, the numbers of its row) of a stretch (feed None is held as NaN)."""
        return STRETCH_KINDS.index(kind), [float(length), math.nan if feed is None else float(feed), *tangent_in,
                                           *tangent_out, float(curvature), float(deviation), float(dwell)]

    def __len__(self) -> int:
        return len(self._kind)

    def __bool__(self) -> bool:
        return len(self._kind) > 0

    def row_item(self, i: int) -> PathBlock:
        row = self._numbers[i]
        d = self.dimension
        length, feed, *rest = row.tolist()
        curvature, deviation, dwell = rest[2 * d:]
        return PathBlock(STRETCH_KINDS[self._kind[i]], float(self.starts[i]), length,
                         None if math.isnan(feed) else feed, int(self._line[i]), row[2:2 + d].copy(),
                         row[2 + d:2 + 2 * d].copy(), curvature, deviation, dwell)

    def column(self, name: str) -> np.ndarray:
        """One field of every stretch as an array: ``start``, ``length``, ``feed`` (NaN where None), ``line``,
        ``curvature``, ``deviation``, ``dwell``, ``kind`` (an index into :data:`STRETCH_KINDS`)."""
        if name == "start":
            return self.starts[:-1]
        if name == "line":
            return self._line
        if name == "kind":
            return self._kind
        d = self.dimension
        return self._numbers[:, {"length": 0, "feed": 1, "curvature": 2 + 2 * d, "deviation": 3 + 2 * d,
                                 "dwell": 4 + 2 * d}[name]]


class _Rows:
    """Rows of a table as they come, in growing buffers (8 bytes a number; no object per row)."""

    def __init__(self, dimension: int, width: int, lines: bool = False):
        self.dimension, self.width = dimension, width
        self.kinds, self.numbers = array("b"), array("d")
        self.lines = array("q") if lines else None

    def add(self, row: tuple, line: int | None = None) -> None:
        kind, numbers = row
        self.kinds.append(kind)
        self.numbers.extend(numbers)
        if self.lines is not None:
            self.lines.append(line)

    def table(self, cls):
        kinds = np.frombuffer(self.kinds, dtype=np.int8) if self.kinds else np.zeros(0, dtype=np.int8)
        numbers = (np.frombuffer(self.numbers, dtype=float) if self.numbers else np.zeros(0)).reshape(-1, self.width)
        if self.lines is None:
            return cls(self.dimension, kinds, numbers)
        lines = np.frombuffer(self.lines, dtype=np.int64) if self.lines else np.zeros(0, dtype=np.int64)
        return cls(self.dimension, kinds, lines, numbers)
