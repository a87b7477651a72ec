"""Results per block of a tool path run, and the scores over its cutting moves alone.

Each step belongs to the block its reference is in (the block whose stretch of the path holds the recorded
curve parameter theta; a step held at a corner belongs to the block that starts there, a blend arc to the
block it leads into). Steps before the reference first moves are the start-up; the cutting moves are the
G1 / G2 / G3 blocks, apart from rapids (G0) and the start-up.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.geometry import ExactContourError
from ..core.gcode import INCH, MM, SourceBlocks
from ..core.interpolation import SETTLE
from ..core.metrics import Scores, score
from ..core.path_tables import STRETCH_KINDS
from .numbers import fixed
from .outputs import write_atomically

__all__ = ["BlockResult", "block_results", "cutting_steps", "cutting_scores", "format_blocks", "write_blocks_csv",
           "block_cells", "block_headings", "block_columns", "motion_end", "feed_unit", "block_codes", "breach_line"]


@dataclass(frozen=True)
class BlockResult:
    """One block of a part program (or one inline move) in a run.

    Attributes
    ----------
    line : int
        Source line (part program) or move number (inline moves).
    number : int or None
        The block's N number, where the program gives one.
    code : str
        G0, G1, G2 or G3.
    programmed_feed : float
        [m/s] its F; on G0 the rapid rate and without F words the schedule's feedrate (times the feed
        override, unless an axis or centripetal bound lowered it); nan where unknown.
    mean_feed : float
        [m/s] the block's length over its time: the feed its share of the cycle time amounts to.
    peak_feed : float
        [m/s] the largest speed the axes reached along the block (the norm of their measured velocities; it
        may pass F by the axes' overshoot while the reference holds F).
    time : float
        [s] the steps whose reference was in the block (waits at its start included), up to the end of the
        run's motion (:func:`motion_end`).
    max_contour_error : float
        [m] the largest exact contour error of those steps.
    max_following_error : tuple
        [m] per axis, the largest |reference - position|.
    verdict : str
        ``held`` or ``exceeded`` against the schedule's contour_tolerance (``-`` without one).
    """

    line: int
    number: int | None
    code: str
    programmed_feed: float
    mean_feed: float
    peak_feed: float
    time: float
    max_contour_error: float
    max_following_error: tuple
    verdict: str


def motion_end(curve, result, windows=None, timeout: float = math.inf, stopped: bool = False) -> int:
    """How many steps of a tool path run its motion takes: up to the step at which the reference has come to
    rest at the path's end and, with in-position ``windows`` [m] (one per axis; None: no check), every axis is
    in position there (within its window of the end point and slower than window / SETTLE, as at an exact
    stop, :class:`~contouring_ros.core.interpolation.InPositionClock`) or ``timeout`` [s] has passed; that
    step included. The steps after it are the run's reserve (the time kept for in-position waits that did
    not happen, and ``settle_time``): no part of the cycle. A run ``stopped`` on the path by monitoring
    (:mod:`contouring_ros.core.monitoring`) ends alike where its reference came to rest. Every step for a run
    that never reached the end (cut short) and for a curve that is not a tool path."""
    theta = np.asarray(result.theta, dtype=float)
    m = len(theta)
    if not hasattr(curve, "blocks") or m == 0 or (theta[-1] != curve.domain[1] and not stopped):
        return m
    moving = np.flatnonzero(theta != theta[-1])
    stop = int(moving[-1]) + 1 if moving.size else 0             # the first step at rest at the end
    if windows is None:
        return stop + 1
    windows = np.asarray(windows, dtype=float)
    dt = float(result.time[1] - result.time[0]) if m > 1 else 1.0
    last = min(m - 1, stop + int(round(timeout / dt))) if math.isfinite(timeout) else m - 1
    position = np.asarray(result.position, dtype=float)[stop:last + 1]
    velocity = np.asarray(result.velocity, dtype=float)[stop:last + 1]
    end = np.asarray(result.reference_position, dtype=float)[stop]
    settled = np.all(np.abs(position - end) <= windows, axis=1) & np.all(np.abs(velocity) * SETTLE <= windows, axis=1)
    return stop + (int(np.argmax(settled)) if settled.any() else last - stop) + 1


def breach_line(breach, curve, axes, sample_time: float) -> str:
    """One line naming a monitoring breach (:class:`~contouring_ros.core.monitoring.Breach`): the error and
    its limit, the block (N number, source line, G word) the reference was in and the time."""
    i = int(_block_index(curve, [breach.theta])[0])
    block = curve.blocks[i]
    number = _sources(curve).number(block.line)
    what = "contour error" if breach.what == "contour" else f"following error of axis {axes[breach.what]}"
    name = f"block N{number} (line {block.line}, {block_codes(curve)[i]})" if number is not None else \
        f"block at line {block.line} ({block_codes(curve)[i]})"
    return (f"monitoring: {what} {breach.error * 1e6:.3f} um passed its limit {breach.limit * 1e6:.3f} um in "
            f"{name} at t = {breach.step * sample_time:.{_time_decimals(sample_time)}f} s (step {breach.step})")


def _sources(curve) -> SourceBlocks:
    """The lines, N numbers and G words of ``curve``'s part program (none for inline moves)."""
    program = getattr(curve, "program", None)
    return getattr(program, "sources", None) or SourceBlocks(getattr(program, "blocks", ()))


def _block_index(curve, theta) -> np.ndarray:
    starts = curve.blocks.column("start")
    return np.clip(np.searchsorted(starts, np.nan_to_num(np.asarray(theta, dtype=float)), side="right") - 1, 0,
                   len(starts) - 1)


def block_codes(curve) -> list:
    """The G word of each block of ``curve``'s path (a blend arc takes its line's word)."""
    blocks = curve.blocks
    kinds = [STRETCH_KINDS[k] for k in blocks.column("kind").tolist()]
    sources = _sources(curve).codes(blocks.column("line"))
    return ["G0" if kind == "rapid" else source if source in ("G2", "G3") else "G2/G3" if kind == "arc" else "G1"
            for kind, source in zip(kinds, sources)]


def cutting_steps(curve, result, end: int | None = None) -> np.ndarray:
    """The steps of the cutting moves: in a G1, G2 or G3 block, once the reference has started moving, and
    before step ``end`` (the end of the motion, :func:`motion_end`; None: every step)."""
    index = _block_index(curve, result.theta)
    cutting = np.array([code != "G0" for code in block_codes(curve)])[index]
    moving = np.flatnonzero(np.asarray(result.theta) != result.theta[0])
    started = np.arange(len(index)) >= (moving[0] if moving.size else len(index))
    return cutting & started & (np.arange(len(index)) < (len(index) if end is None else end))


def cutting_scores(curve, result, end: int | None = None) -> Scores | None:
    """The scores of :func:`cutting_steps` alone (None for a curve that is not a tool path, or without any)."""
    if not hasattr(curve, "blocks"):
        return None
    kept = cutting_steps(curve, result, end)
    if not kept.any():
        return None
    return score(curve, result.time[kept], result.position[kept], result.reference_position[kept],
                 result.estimate_vector[kept], result.command[kept], theta=result.theta[kept])[0]


def block_results(curve, result, schedule=None, tolerance: float = 0.0, exact=None, end: int | None = None) -> list:
    """One :class:`BlockResult` per source block the run reached, in program order; ``schedule`` (the feed
    plan) gives each block's programmed feed limit, ``tolerance`` [m] the verdict; ``end``: the steps of the
    motion (:func:`motion_end`; None: every step)."""
    end = len(result.time) if end is None else int(end)
    index = _block_index(curve, result.theta)[:end]
    codes = block_codes(curve)
    limits = getattr(schedule, "limits", None)
    errors = (exact or ExactContourError(curve))(result.position[:end], near=result.theta[:end]).distance
    following = np.abs(np.asarray(result.reference_position)[:end] - np.asarray(result.position)[:end])
    speed = np.linalg.norm(np.asarray(result.velocity)[:end], axis=1)
    dt = float(result.time[1] - result.time[0]) if len(result.time) > 1 else 0.0
    sources = _sources(curve)
    block_lines = curve.blocks.column("line").tolist()
    lines = list(dict.fromkeys(block_lines))
    members_of = {}
    for i, line in enumerate(block_lines):
        members_of.setdefault(line, []).append(i)
    counts = np.bincount(index, minlength=len(curve.blocks))
    rows = []
    for line in lines:
        members = members_of[line]
        if not counts[members].any():
            continue
        steps = np.isin(index, members)
        main = next((i for i in members if curve.blocks[i].kind != "blend"), members[0])
        block = curve.blocks[main]
        feed = block.feed if block.feed is not None else \
            limits[main].feed if limits is not None and limits[main].bound in ("rapid", "feedrate") else np.nan
        worst = float(errors[steps].max())
        verdict = "-" if not tolerance else ("held" if worst <= tolerance else "exceeded")
        time = float(steps.sum() * dt)
        length = float(sum(curve.blocks[i].length for i in members))
        rows.append(BlockResult(line, sources.number(line), codes[main], float(feed),
                                length / time if time > 0.0 else np.nan, float(speed[steps].max()), time, worst,
                                tuple(float(v) for v in following[steps].max(axis=0)), verdict))
    return rows


def feed_unit(curve) -> tuple:
    """(metres per minute of the unit, its name) of the feeds of ``curve``'s results: the part program's own
    unit per minute (G20: in/min, G21: mm/min; :attr:`~contouring_ros.core.gcode.Program.unit`); mm/min for
    inline moves."""
    unit = getattr(getattr(curve, "program", None), "unit", MM)
    return (INCH, "in/min") if unit == INCH else (MM, "mm/min")


#: decimals of each quantity as printed: feeds to 0.1 mm/min (0.001 in/min: 0.025 mm/min), errors to 1 nm
#: (a linear scale's resolution), times to the sample time
FEED_DECIMALS = {"mm/min": 1, "in/min": 3}
ERROR_DECIMALS = 3


def _time_decimals(sample_time: float) -> int:
    return max(0, min(9, math.ceil(-math.log10(sample_time) - 1e-9))) if sample_time > 0.0 else 3


def block_cells(row: BlockResult, curve=None, sample_time: float = 1e-3) -> list:
    """One row of the table as text: feeds in the program's unit per minute (:func:`feed_unit`), times to
    the sample time, errors in um to 1 nm."""
    per_minute, name = feed_unit(curve)
    scale, decimals = 60.0 / per_minute, FEED_DECIMALS[name]

    def feed(value):
        return "" if not np.isfinite(value) else fixed(value * scale, decimals)
    return [str(row.line), "" if row.number is None else str(row.number), row.code, feed(row.programmed_feed),
            feed(row.mean_feed), feed(row.peak_feed), fixed(row.time, _time_decimals(sample_time)),
            fixed(row.max_contour_error * 1e6, ERROR_DECIMALS),
            *(fixed(v * 1e6, ERROR_DECIMALS) for v in row.max_following_error), row.verdict]


def block_columns(axes, curve=None) -> list:
    """The CSV's column names (each with its unit)."""
    unit = feed_unit(curve)[1].replace("/", "_per_")
    return ["line", "N", "G", f"programmed_feed_{unit}", f"mean_feed_{unit}", f"peak_feed_{unit}", "time_s",
            "max_contour_error_um"] + [f"max_following_error_{a}_um" for a in axes] + ["tolerance"]


def block_headings(axes, curve=None) -> list:
    """The table's column headings, for reading, with their units (the HTML report's)."""
    unit = feed_unit(curve)[1]
    return ["line", "N", "G", f"F [{unit}]", f"mean feed [{unit}]", f"peak feed [{unit}]", "time [s]",
            "max contour [um]"] + [f"max following {a} [um]" for a in axes] + ["tolerance"]


def format_blocks(rows: list, axes, curve=None, sample_time: float = 1e-3) -> str:
    """The per-block table as plain text for a terminal: a line naming the units, then short headings (one
    column of 8-10 characters per quantity, so three axes fit 100 columns)."""
    unit = feed_unit(curve)[1]
    header = ["line", "N", "G", "F", "mean", "peak", "time", "contour"] + [f"follow {a}" for a in axes] + ["tol"]
    body = [block_cells(row, curve, sample_time) for row in rows]
    widths = [max(len(h), *(len(r[j]) for r in body)) if body else len(h) for j, h in enumerate(header)]
    caption = f"feeds [{unit}] (mean: length / time; peak: the axes'); time [s]; largest errors [um]"
    return "\n".join([caption] + [" ".join(c.rjust(w) for c, w in zip(r, widths)).rstrip()
                                    for r in [header] + body])


def write_blocks_csv(rows: list, axes, path, curve=None, sample_time: float = 1e-3) -> Path:
    """The per-block table as CSV (column names carry the unit; the numbers as the table rounds them)."""
    path = Path(path)

    def write(tmp):
        with open(tmp, "w", newline="") as stream:
            writer = csv.writer(stream)
            writer.writerow(block_columns(axes, curve))
            writer.writerows(block_cells(row, curve, sample_time) for row in rows)
    write_atomically(path, write)
    return path
