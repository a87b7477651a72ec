"""Recorded runs made ready to draw: one :class:`Trace` per run, with its legend name, its colour, its curve
and exact contour error, whether it diverged, its reference path and the magnification its error is drawn at.

Every figure and the HTML report are drawn from these traces, so that a run has one name and one colour in all
of them. Lengths here are in metres. Non-finite samples (a diverged run) are made nan: gaps in a line. No
matplotlib here (:mod:`contouring_ros.records.figures` draws).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .bag import RecordedRun
from .comparison import run_names
from ..experiment.build import build_curve
from ..core.geometry import ExactContourError
from ..errors import ContouringError

__all__ = ["PALETTE", "Trace", "traces_of", "finite_or_nan", "axis_union", "axis_groups", "worst_step",
           "reference_paths", "magnified", "path_span", "auto_magnification"]

#: the runs' colours, in the order of the runs
PALETTE = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf",
           "#bcbd22", "#7f7f7f")


@dataclass
class Trace:
    """One run, ready to draw (lengths in metres)."""

    name: str
    colour: str
    run: RecordedRun
    experiment: object            # the parsed Experiment, or None where the stored YAML does not parse
    curve: object                 # its reference Curve, or None
    distance: np.ndarray          # exact contour error per step (nan where the position is not finite)
    vector: np.ndarray            # foot point - position per step
    path_length: np.ndarray       # distance travelled along the reference up to each step
    diverged: bool                # see _diverged

    @property
    def axes(self) -> list:
        return list(self.run.axes)

    @property
    def time(self) -> np.ndarray:
        return self.run.result.time


def finite_or_nan(values) -> np.ndarray:
    """``values`` as floats with every non-finite entry made nan (a gap in a line)."""
    values = np.asarray(values, dtype=float)
    return np.where(np.isfinite(values), values, np.nan)


def _trace(name: str, colour: str, run: RecordedRun) -> Trace:
    result = run.result
    steps, n = len(result.time), len(run.axes)
    experiment = run.experiment
    curve = None
    if experiment is not None:
        try:
            curve = build_curve(experiment)
        except ContouringError:
            curve = None
    distance, vector = np.full(steps, np.nan), np.full((steps, n), np.nan)
    position, theta = finite_or_nan(result.position).reshape(steps, n), finite_or_nan(result.theta)
    ok = np.isfinite(position).all(axis=1) & np.isfinite(theta)
    if curve is not None and ok.any():
        with np.errstate(all="ignore"):
            foot = ExactContourError(curve)(position[ok], near=theta[ok])
        distance[ok], vector[ok] = finite_or_nan(foot.distance), finite_or_nan(foot.vector)
    travelled = np.linalg.norm(np.diff(finite_or_nan(result.reference_position).reshape(steps, n), axis=0), axis=1)
    path_length = np.concatenate([[0.0], np.nancumsum(travelled)])[:steps]
    trace = Trace(name, colour, run, experiment, curve, distance, vector, path_length, False)
    trace.diverged = _diverged(trace)
    return trace


def _diverged(trace: Trace) -> bool:
    """Whether a run diverged: its bag says so, a signal is not finite, or its contour error exceeds a
    tenth of the path's size."""
    result = trace.run.result
    if any("diverged" in warning for warning in trace.run.warnings) or not all(
            np.isfinite(a).all() for a in (result.position, result.command, result.correction)):
        return True
    worst = np.nanmax(trace.distance, initial=0.0)
    return bool(worst > 0.1 * path_span(reference_paths([trace]) or [finite_or_nan(result.reference_position)]))


def traces_of(runs: list) -> list:
    """A :class:`Trace` of each (label, RecordedRun) of ``runs``, named by
    :func:`contouring_ros.records.comparison.run_names` and coloured from :data:`PALETTE` in turn."""
    if not runs:
        raise ValueError("no runs to draw")
    return [_trace(name, PALETTE[k % len(PALETTE)], run)
            for k, ((_, run), name) in enumerate(zip(runs, run_names(runs)))]


def axis_union(traces) -> list:
    """Every axis name of the runs, in order of appearance."""
    return list(dict.fromkeys(axis for t in traces for axis in t.axes))


def axis_groups(traces) -> list:
    """(axes, traces) for each set of axes among the runs: runs of one set share a path plot."""
    groups: dict = {}
    for t in traces:
        groups.setdefault(tuple(t.axes), []).append(t)
    return list(groups.items())


def worst_step(trace: Trace):
    """The step of the largest contour error, or None."""
    return int(np.nanargmax(trace.distance)) if np.isfinite(trace.distance).any() else None


def _reference_points(trace: Trace) -> np.ndarray:
    """The planned reference path (the schedule's parameter range of the curve), (m, n) in metres."""
    if trace.curve is None:
        return np.empty((0, len(trace.axes)))
    lo, hi = trace.curve.domain
    schedule = trace.experiment.schedule
    if schedule.get("theta_start") is not None and schedule.get("theta_end") is not None:
        lo, hi = sorted((float(schedule["theta_start"]), float(schedule["theta_end"])))
    return np.asarray(trace.curve.point(np.linspace(lo, hi, 4000)))


def reference_paths(traces) -> list:
    """The distinct reference paths of ``traces`` (runs of one curve and schedule share theirs)."""
    unique = {}
    for t in traces:
        key = repr((t.experiment.curve, t.experiment.schedule)) if t.experiment else id(t)
        unique.setdefault(key, _reference_points(t))
    return list(unique.values())


def magnified(trace: Trace, gain: float) -> np.ndarray:
    """Actual positions drawn ``gain`` times as far from their foot points: F + gain (P - F)."""
    return finite_or_nan(trace.run.result.position) - (gain - 1.0) * trace.vector


def _extents(points: list) -> np.ndarray:
    """The extent along each axis of some (m, n) point sets (zeros where there are no finite points)."""
    finite = [p[np.isfinite(p).all(axis=1)] for p in points if len(p)]
    finite = [p for p in finite if len(p)]
    return np.max([np.ptp(p, axis=0) for p in finite], axis=0) if finite else np.zeros(1)


def path_span(points: list) -> float:
    """The largest extent over the axes of some (m, n) point sets; 1 mm where there is none."""
    span = float(_extents(points).max())
    return span if span > 0.0 else 1e-3


def auto_magnification(traces, references: list) -> float:
    """A round factor that draws the largest contour error at about 15 % of the path's narrowest side
    (sides under 1 % of the widest left out), at least 1. Runs whose error is that large already (diverged)
    do not count."""
    extents = _extents(references)
    extents = extents[extents > 0.01 * extents.max()] if extents.max() > 0.0 else np.array([1e-3])
    target = 0.15 * float(extents.min())
    worst = max((float(np.nanmax(t.distance)) for t in traces if np.isfinite(t.distance).any()
                 and 0.0 < np.nanmax(t.distance) < target), default=0.0)
    return float(f"{target / worst:.1g}") if worst > 0.0 else 1.0

