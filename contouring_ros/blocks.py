"""Results per block of a tool path run, and the scores over its cutting moves alone.

Each step belongs to the block its reference is in (the block whose stretch of the path holds the recorded
curve parameter theta; a step held at a corner belongs to the block that starts there, a blend arc to the
block it leads into). Steps before the reference first moves are the start-up; the cutting moves are the
G1 / G2 / G3 blocks, apart from rapids (G0) and the start-up.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .core.geometry import ExactContourError
from .core.metrics import Scores, score
from .errors import write_atomically

__all__ = ["BlockResult", "block_results", "cutting_steps", "cutting_scores", "format_blocks", "write_blocks_csv",
           "block_cells", "block_headings", "BLOCK_COLUMNS"]


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
    achieved_feed : float
        [m/s] the largest speed the axes reached along the block (the norm of their measured velocities).
    time : float
        [s] the steps whose reference was in the block (waits at its start included).
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
    achieved_feed: float
    time: float
    max_contour_error: float
    max_following_error: tuple
    verdict: str


def _block_index(curve, theta) -> np.ndarray:
    starts = np.array([b.start for b in curve.blocks])
    return np.clip(np.searchsorted(starts, np.nan_to_num(np.asarray(theta, dtype=float)), side="right") - 1, 0,
                   len(starts) - 1)


def _codes(curve) -> list:
    """The G word of each block of ``curve``'s path (a blend arc takes its line's word)."""
    program = {b.line: b for b in getattr(getattr(curve, "program", None), "blocks", [])}
    out = []
    for block in curve.blocks:
        source = program.get(block.line)
        if block.kind == "rapid":
            out.append("G0")
        elif source is not None and source.kind == "arc":
            out.append("G2" if source.clockwise else "G3")
        elif block.kind == "arc":
            out.append("G2/G3")
        else:
            out.append("G1")
    return out


def cutting_steps(curve, result) -> np.ndarray:
    """The steps of the cutting moves: in a G1, G2 or G3 block, once the reference has started moving."""
    index = _block_index(curve, result.theta)
    cutting = np.array([code != "G0" for code in _codes(curve)])[index]
    moving = np.flatnonzero(np.asarray(result.theta) != result.theta[0])
    started = np.arange(len(index)) >= (moving[0] if moving.size else len(index))
    return cutting & started


def cutting_scores(curve, result) -> Scores | None:
    """The scores of :func:`cutting_steps` alone (None for a curve that is not a tool path, or without any)."""
    if not hasattr(curve, "blocks"):
        return None
    kept = cutting_steps(curve, result)
    if not kept.any():
        return None
    return score(curve, result.time[kept], result.position[kept], result.reference_position[kept],
                 result.estimate_vector[kept], result.command[kept], theta=result.theta[kept])[0]


def block_results(curve, result, schedule=None, tolerance: float = 0.0, exact=None) -> list:
    """One :class:`BlockResult` per source block the run reached, in program order; ``schedule`` (the feed
    plan) gives each block's programmed feed limit, ``tolerance`` [m] the verdict."""
    index = _block_index(curve, result.theta)
    codes = _codes(curve)
    limits = getattr(schedule, "limits", None)
    errors = (exact or ExactContourError(curve))(result.position, near=result.theta).distance
    following = np.abs(np.asarray(result.reference_position) - np.asarray(result.position))
    speed = np.linalg.norm(np.asarray(result.velocity), axis=1)
    dt = float(result.time[1] - result.time[0]) if len(result.time) > 1 else 0.0
    program = {b.line: b for b in getattr(getattr(curve, "program", None), "blocks", [])}
    rows, lines = [], []
    for i, block in enumerate(curve.blocks):
        if block.line not in lines:
            lines.append(block.line)
    for line in lines:
        members = [i for i, b in enumerate(curve.blocks) if b.line == line]
        steps = np.isin(index, members)
        if not steps.any():
            continue
        main = next((i for i in members if curve.blocks[i].kind != "blend"), members[0])
        block = curve.blocks[main]
        feed = block.feed if block.feed is not None else \
            limits[main].feed if limits is not None and limits[main].bound in ("rapid", "feedrate") else np.nan
        worst = float(errors[steps].max())
        verdict = "-" if not tolerance else ("held" if worst <= tolerance else "exceeded")
        source = program.get(line)
        rows.append(BlockResult(line, getattr(source, "number", None), codes[main], float(feed),
                                float(speed[steps].max()), float(steps.sum() * dt), worst,
                                tuple(float(v) for v in following[steps].max(axis=0)), verdict))
    return rows


BLOCK_COLUMNS = ["line", "N", "G", "programmed_feed_mm_per_min", "achieved_feed_mm_per_min", "time_s",
                 "max_contour_error_um"]


def block_cells(row: BlockResult) -> list:
    """One row of the table as text: feeds in mm/min, errors in um."""
    return [str(row.line), "" if row.number is None else str(row.number), row.code,
            "" if np.isnan(row.programmed_feed) else f"{row.programmed_feed * 60e3:.6g}",
            f"{row.achieved_feed * 60e3:.6g}", f"{row.time:.6g}", f"{row.max_contour_error * 1e6:.6g}",
            *(f"{v * 1e6:.6g}" for v in row.max_following_error), row.verdict]


def _header(axes) -> list:
    return BLOCK_COLUMNS + [f"max_following_error_{a}_um" for a in axes] + ["tolerance"]


def block_headings(axes) -> list:
    """The table's column headings, for reading (the CSV's names are BLOCK_COLUMNS and the axes')."""
    return ["line", "N", "G", "F [mm/min]", "achieved [mm/min]", "time [s]", "max contour [um]"] + \
        [f"max following {a} [um]" for a in axes] + ["tolerance"]


def format_blocks(rows: list, axes) -> str:
    """The per-block table as plain text (feeds in mm/min, errors in um)."""
    header = block_headings(axes)
    body = [block_cells(row) for row in rows]
    widths = [max(len(h), *(len(r[j]) for r in body)) if body else len(h) for j, h in enumerate(header)]
    return "\n".join("  ".join(c.rjust(w) for c, w in zip(r, widths)) for r in [header] + body)


def write_blocks_csv(rows: list, axes, path) -> Path:
    """The per-block table as CSV (column names carry the unit)."""
    path = Path(path)
    def write(tmp):
        with open(tmp, "w", newline="") as stream:
            writer = csv.writer(stream)
            writer.writerow(_header(axes))
            writer.writerows(block_cells(row) for row in rows)
    write_atomically(path, write)
    return path
