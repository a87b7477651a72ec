"""Offline analysis of recorded runs: comparisons, estimator replay, figures and an HTML report.

Nothing here needs ROS: bags are read with :mod:`contouring_ros.records.bag`, figures drawn with matplotlib.
"""
from __future__ import annotations

import base64
import html
import io
import weakref
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from .bag import RecordedRun
from .blocks import block_cells, block_codes, block_headings, block_results, cutting_scores, feed_unit
from ..experiment.build import build_curve, build_estimator, build_schedule
from ..experiment.catalogue import ESTIMATORS
from ..experiment.ros_yaml import read_yaml
from ..experiment.validate import validate_section
from ..core.curves import ToolPath
from ..core.geometry import ExactContourError
from ..core.interpolation import Reference
from ..errors import ConfigError, ContouringError, OutputError
from .outputs import write_atomically
from ..core.feed_control import parse_feed_events
from .scoring import SCORE_ROWS, breach_of, curve_of, format_scores, motion_steps
from ..experiment.settings import differences

__all__ = ["compare_table", "experiment_differences", "format_differences",
           "parse_estimator_spec", "EstimatorReplay", "replay_estimators", "run_names",
           "figures", "write_figures", "html_report"]


def compare_table(named: list, baseline: int = 0, axes=None) -> str:
    """Scores side by side, then each run's main metrics as a ratio to the baseline run."""
    table = format_scores(named, axes)
    base_name, base = named[baseline]
    lines = [table, "", f"ratio to {base_name}:"]
    width = max(len(label) for label, _ in SCORE_ROWS)
    columns = [max(12, len(name)) for name, _ in named]
    lines.append("  ".join([" " * width] + [name.rjust(w) for (name, _), w in zip(named, columns)]))
    for label, get in SCORE_ROWS:
        reference = get(base)
        cells = [(f"{get(scores) / reference:.3g}" if reference else "-").rjust(w)
                 for (_, scores), w in zip(named, columns)]
        lines.append("  ".join([label.split(" [")[0].ljust(width)] + cells))
    return "\n".join(lines)


def experiment_differences(runs: list) -> dict:
    """Grid key (``ccc.kp``, ``curve.h``) -> each run's value, for every key of the experiment files stored in
    (label, RecordedRun) ``runs`` whose value is not the same in all (:func:`contouring_ros.studies.sweep.differences`;
    the experiment's name left out: the runs are named by it anyway). Empty for one run, or where a run's
    bag holds no experiment it can read."""
    if len(runs) < 2:
        return {}
    try:
        datas = [read_yaml(run.experiment_text, label) for label, run in runs]
    except ContouringError:
        return {}
    if not all(isinstance(data, dict) for data in datas):
        return {}
    return {key: values for key, values in differences(datas).items() if key != "experiment.name"}


def format_differences(names: list, changed: dict) -> str:
    """The lines of a text report saying how compared experiments differ (:func:`experiment_differences`)."""
    if not changed:
        return "the experiments differ in nothing but their names" if len(names) > 1 else ""
    width = max(len(key) for key in changed)
    lines = ["how the experiments differ:"]
    for key, values in changed.items():
        lines.append(f"  {key.ljust(width)}  " + "; ".join(f"{name}: {'-' if value is None else value}"
                                                         for name, value in zip(names, values)))
    return "\n".join(lines)


def parse_estimator_spec(spec: str) -> dict:
    """'newton:k_prime=800,tolerance=1e-10' -> {'type': 'newton', 'k_prime': 800.0, 'tolerance': 1e-10}."""
    name, _, options = spec.partition(":")
    section = {"type": name}
    for item in filter(None, options.split(",")):
        key, sep, value = item.partition("=")
        if not sep:
            raise ConfigError(f"--estimator {spec}: expected key=value, got {item!r}")
        try:
            section[key] = int(value)
        except ValueError:
            try:
                section[key] = float(value)
            except ValueError:
                section[key] = value
    integer_keys = {k for k, p in (ESTIMATORS[name] if name in ESTIMATORS else {}).items() if p.kind == "int"}
    return {k: (float(v) if isinstance(v, int) and k not in integer_keys else v) for k, v in section.items()}


@dataclass
class EstimatorReplay:
    """How one estimator tracks the exact contour error over a recorded run (lengths in metres)."""

    name: str
    estimate: np.ndarray          # |estimate| per step
    deviation_max: float
    deviation_rms: float


def replay_estimators(run: RecordedRun, specs: list, progress: bool = False) -> tuple[np.ndarray, list]:
    """Run each estimator of ``specs`` over the recorded reference and positions (a spec of the recorded
    estimator's type changes only the keys it names of the recorded section).

    Returns the exact contour error per step and, first for the recorded estimate and then for each spec,
    an :class:`EstimatorReplay`.
    """
    experiment = run.require_experiment()
    curve = curve_of(run)
    result = run.result
    exact = ExactContourError(curve)(result.position, near=result.theta).distance
    recorded = np.linalg.norm(result.estimate_vector, axis=1)
    replays = [_replay("recorded (" + experiment.estimator.get("type", "?") + ")", recorded, exact)]
    n = len(run.axes)
    for spec in specs:
        # of the recorded estimator's type, the recorded section with the spec's keys changed
        # (newton:k_prime=800 on a Newton run keeps its c_prime); of another type, the spec alone
        recorded_keys = {k: v for k, v in experiment.estimator.items() if v is not None}    # None: left to default
        given = {**recorded_keys, **spec} if spec["type"] == experiment.estimator.get("type") else spec
        # the estimator registry (built-in and plugin types alike): its keys, its constraints, its factory
        section = validate_section("--estimator", spec["type"], ESTIMATORS, given, experiment.axes)
        estimator = build_estimator(_with_estimator(experiment, section), curve)
        norms = np.empty(len(result.time))
        for k in tqdm(range(len(result.time)), desc=f"replaying {spec['type']}", disable=not progress,
                      leave=False, mininterval=0.5):
            ref = Reference(theta=result.theta[k], theta_dot=0.0, theta_ddot=0.0,
                            position=result.reference_position[k, :n], velocity=result.reference_velocity[k, :n],
                            acceleration=result.reference_acceleration[k, :n])
            norms[k] = np.linalg.norm(estimator.step(ref, result.position[k]).vector)
        label = spec["type"] + "".join(f" {k}={v:g}" if isinstance(v, float) else f" {k}={v}"
                                       for k, v in spec.items() if k != "type")
        replays.append(_replay(label, norms, exact))
    return exact, replays


def _with_estimator(experiment, section):
    from dataclasses import replace
    return replace(experiment, estimator=section)


def _replay(name, estimate, exact) -> EstimatorReplay:
    deviation = np.abs(estimate - exact)
    return EstimatorReplay(name, estimate, float(deviation.max()), float(np.sqrt(np.mean(deviation ** 2))))


# --- figures -----------------------------------------------------------------------------------------
#
# Every figure is drawn from _Trace objects, one per run (its legend name, its colour, its curve and exact
# contour error), so that a run has one name and one colour in all of them. Units: paths in mm, errors in
# um, time in s, actuator signals in the command's units. Non-finite samples (a diverged run) are gaps.

PALETTE = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf",
           "#bcbd22", "#7f7f7f")
ERROR_MAP = "viridis"
DIVERGED = "diverged"         # the gid of a diverged run's lines
FIGURE_DPI = 130


@dataclass
class _Trace:
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


def _finite(values) -> np.ndarray:
    """``values`` as floats with every non-finite entry made nan (a gap in a line)."""
    values = np.asarray(values, dtype=float)
    return np.where(np.isfinite(values), values, np.nan)


def _stored_name(run: RecordedRun) -> str | None:
    experiment = run.experiment
    name = experiment and (experiment.info.get("experiment") or {}).get("name")
    return str(name) if name else None


def run_names(runs: list) -> list:
    """Legend names of (label, RecordedRun) pairs: the experiment name stored in each bag (the label where
    the bag has none); runs of one name are told apart by what their labels add to it (a bag's
    timestamp) where the labels differ, else numbered."""
    names = [_stored_name(run) or label for label, run in runs]
    labels = {name: [label for (label, _), other in zip(runs, names) if other == name] for name in names}
    out, seen = [], Counter()
    for (label, _), name in zip(runs, names):
        seen[name] += 1
        same = labels[name]
        if len(same) == 1:
            out.append(name)
        elif len(set(same)) == len(same):
            extra = label[len(name):].strip(" _-") if label.startswith(name) else label
            out.append(f"{name} ({extra})" if extra else name)
        else:
            out.append(f"{name} #{seen[name]}")
    counts, seen = Counter(out), Counter()
    for k, name in enumerate(out):          # labels that differ only in separators
        seen[name] += 1
        out[k] = f"{name} #{seen[name]}" if counts[name] > 1 else name
    return out


def _trace(name: str, colour: str, run: RecordedRun) -> _Trace:
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
    position, theta = _finite(result.position).reshape(steps, n), _finite(result.theta)
    ok = np.isfinite(position).all(axis=1) & np.isfinite(theta)
    if curve is not None and ok.any():
        with np.errstate(all="ignore"):
            foot = ExactContourError(curve)(position[ok], near=theta[ok])
        distance[ok], vector[ok] = _finite(foot.distance), _finite(foot.vector)
    travelled = np.linalg.norm(np.diff(_finite(result.reference_position).reshape(steps, n), axis=0), axis=1)
    path_length = np.concatenate([[0.0], np.nancumsum(travelled)])[:steps]
    trace = _Trace(name, colour, run, experiment, curve, distance, vector, path_length, False)
    trace.diverged = _diverged(trace)
    return trace


def _diverged(trace: _Trace) -> bool:
    """Whether a run diverged: its bag says so, a signal is not finite, or its contour error exceeds a
    tenth of the path's size."""
    result = trace.run.result
    if any("diverged" in warning for warning in trace.run.warnings) or not all(
            np.isfinite(a).all() for a in (result.position, result.command, result.correction)):
        return True
    worst = np.nanmax(trace.distance, initial=0.0)
    return bool(worst > 0.1 * _span(_references([trace]) or [_finite(result.reference_position)]))


def _traces(runs: list) -> list:
    if not runs:
        raise ValueError("no runs to draw")
    return [_trace(name, PALETTE[k % len(PALETTE)], run)
            for k, ((_, run), name) in enumerate(zip(runs, run_names(runs)))]


def _axis_union(traces) -> list:
    """Every axis name of the runs, in order of appearance."""
    return list(dict.fromkeys(axis for t in traces for axis in t.axes))


def _axis_groups(traces) -> list:
    """(axes, traces) for each set of axes among the runs: runs of one set share a path plot."""
    groups: dict = {}
    for t in traces:
        groups.setdefault(tuple(t.axes), []).append(t)
    return list(groups.items())


def _worst_step(trace: _Trace):
    """The step of the largest contour error, or None."""
    return int(np.nanargmax(trace.distance)) if np.isfinite(trace.distance).any() else None


def _reference_points(trace: _Trace) -> np.ndarray:
    """The planned reference path (the schedule's parameter range of the curve), (m, n) in metres."""
    if trace.curve is None:
        return np.empty((0, len(trace.axes)))
    lo, hi = trace.curve.domain
    schedule = trace.experiment.schedule
    if schedule.get("theta_start") is not None and schedule.get("theta_end") is not None:
        lo, hi = sorted((float(schedule["theta_start"]), float(schedule["theta_end"])))
    return np.asarray(trace.curve.point(np.linspace(lo, hi, 4000)))


def _references(traces) -> list:
    """The distinct reference paths of ``traces`` (runs of one curve and schedule share theirs)."""
    unique = {}
    for t in traces:
        key = repr((t.experiment.curve, t.experiment.schedule)) if t.experiment else id(t)
        unique.setdefault(key, _reference_points(t))
    return list(unique.values())


def _magnified(trace: _Trace, gain: float) -> np.ndarray:
    """Actual positions drawn ``gain`` times as far from their foot points: F + gain (P - F)."""
    return _finite(trace.run.result.position) - (gain - 1.0) * trace.vector


def _extents(points: list) -> np.ndarray:
    """The extent along each axis of some (m, n) point sets (zeros where there are no finite points)."""
    finite = [p[np.isfinite(p).all(axis=1)] for p in points if len(p)]
    finite = [p for p in finite if len(p)]
    return np.max([np.ptp(p, axis=0) for p in finite], axis=0) if finite else np.zeros(1)


def _span(points: list) -> float:
    """The largest extent over the axes of some (m, n) point sets; 1 mm where there is none."""
    span = float(_extents(points).max())
    return span if span > 0.0 else 1e-3


def _auto_magnification(traces, references: list) -> float:
    """A round factor that draws the largest contour error at about 15 % of the path's narrowest side
    (sides under 1 % of the widest left out), at least 1. Runs whose error is that large already (diverged)
    do not count."""
    extents = _extents(references)
    extents = extents[extents > 0.01 * extents.max()] if extents.max() > 0.0 else np.array([1e-3])
    target = 0.15 * float(extents.min())
    worst = max((float(np.nanmax(t.distance)) for t in traces if np.isfinite(t.distance).any()
                 and 0.0 < np.nanmax(t.distance) < target), default=0.0)
    return float(f"{target / worst:.1g}") if worst > 0.0 else 1.0


def _figure(title: str, width: float, height: float):
    """A matplotlib Figure on the Agg canvas, outside pyplot (nothing to close, no global state)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    fig.suptitle(title, fontsize=13, fontweight="bold")
    return fig


def _run_legend(fig, traces, extra=()):
    """One legend for the whole figure: a line of each run's colour with its name, after ``extra``."""
    from matplotlib.lines import Line2D
    handles = list(extra) + [Line2D([], [], color=t.colour, lw=2.0, label=t.name) for t in traces]
    entry = 0.7 + 0.075 * max(len(h.get_label()) for h in handles)       # inches at font size 9
    columns = max(1, min(len(handles), 3, int(fig.get_figwidth() // entry)))
    fig.legend(handles=handles, loc="outside lower center", ncols=columns, fontsize=9, frameon=False)


def _style(ax, xlabel: str = "", ylabel: str = "", title: str | None = None, zlabel: str | None = None):
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if zlabel is not None:
        ax.set_zlabel(zlabel)
    if title:
        ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.35, lw=0.6)


def _series(ax, traces, x, y, suffix: str = "", signed: bool = False, **style):
    """One line per run: ``x(trace)`` against ``y(trace)`` in the run's colour, labelled name + suffix;
    then the y scale that shows them all (see :func:`_fit_scale`)."""
    for t in traces:
        ax.plot(_finite(x(t)), _finite(y(t)), color=t.colour, label=t.name + suffix,
                gid=DIVERGED if t.diverged else None, **{"lw": 1.1, **style})
    _fit_scale(ax, signed)


def _fit_scale(ax, signed: bool):
    """Scales that keep every run readable beside a diverged one. Magnitudes whose peaks span over two
    decades get a logarithmic y axis; signed data get limits that fit the runs that did not diverge, a
    diverged run ten times larger running off them (named in the corner)."""
    lines = [(line, float(np.nanmax(np.abs(y)))) for line, y in
             ((line, np.asarray(line.get_ydata(), float)) for line in ax.get_lines()) if np.isfinite(y).any()]
    if not signed:
        peaks = sorted(peak for _, peak in lines if peak > 0.0)
        if len(peaks) > 1 and peaks[-1] > 100.0 * peaks[0]:
            ax.set_yscale("log", nonpositive="mask")
        return
    normal = [peak for line, peak in lines if line.get_gid() != DIVERGED]
    bound = 1.1 * max(normal, default=0.0)
    off = [line.get_label() for line, peak in lines if line.get_gid() == DIVERGED and peak > 10.0 * bound]
    if off and bound > 0.0:
        ax.set_ylim(-bound, bound)
        ax.text(0.99, 0.96, "off scale: " + ", ".join(off), transform=ax.transAxes, ha="right", va="top",
                fontsize=7, color="0.3")


def _view_limits(ax, view, references, paths, span):
    """Axis limits of a path view: the reference paths with a margin, widened to the actual paths by at
    most half the path's size (a diverged path leaves the frame instead of shrinking the reference)."""
    setters = (ax.set_xlim, ax.set_ylim, getattr(ax, "set_zlim", None))
    extents = []
    for setter, i in zip(setters, view):
        ref = np.concatenate([r[:, i] for r in references] or [np.empty(0)])
        shown = np.concatenate([p[:, i] for p in paths] or [np.empty(0)])
        ref, shown = ref[np.isfinite(ref)], shown[np.isfinite(shown)]
        lo, hi = (ref.min(), ref.max()) if ref.size else (shown.min(), shown.max()) if shown.size else (0.0, 0.0)
        if shown.size:
            lo, hi = max(min(lo, shown.min()), lo - 0.5 * span), min(max(hi, shown.max()), hi + 0.5 * span)
        pad = 0.04 * span
        setter((lo - pad) * 1e3, (hi + pad) * 1e3)
        extents.append(hi - lo + 2 * pad)
    if len(view) == 3:
        _style_3d(ax, extents)
    elif max(extents) < 2.5 * min(extents):
        ax.set_aspect("equal", adjustable="box")


def _style_3d(ax, extents):
    """A 3-D box close to the path's proportions (no side under half the longest: a tall helix stays
    readable), with few, small tick labels."""
    from matplotlib.ticker import MaxNLocator
    ax.set_box_aspect([max(e, 0.5 * max(extents)) for e in extents], zoom=0.82)
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(4))
        axis.labelpad = 2
    ax.tick_params(labelsize=7, pad=0)


def _new_view(container, position, view):
    return container.add_subplot(*position, projection="3d" if len(view) == 3 else None)


def _label_view(ax, axes, view, title):
    labels = [f"{axes[i]} [mm]" for i in view]
    _style(ax, labels[0], labels[1], title, labels[2] if len(view) == 3 else None)


def _path_views(n: int) -> list:
    """Axis index tuples to draw a path of n axes in: 3-D and the three projections, or the plane."""
    return [(0, 1, 2), (0, 1), (0, 2), (1, 2)] if n >= 3 else [(0, 1)] if n == 2 else []


def _draw_path_view(ax, group, axes, view, gains, span):
    references = _references(group)
    for ref in references:
        ax.plot(*(ref[:, i] * 1e3 for i in view), color="black", lw=0.8)
    paths = []
    for t, gain in zip(group, gains):
        shown = _magnified(t, gain)
        paths.append(shown)
        ax.plot(*(shown[:, i] * 1e3 for i in view), color=t.colour, lw=1.2, label=t.name)
        k = _worst_step(t)
        if k is not None:
            ax.plot(*([shown[k, i] * 1e3] for i in view), "o", ms=8, mfc="none", mew=1.5, color=t.colour)
    _view_limits(ax, view, references, paths, span)
    plane = "3-D path" if len(view) == 3 else f"{axes[view[0]]}{axes[view[1]]} projection" if len(axes) > 2 \
        else f"{axes[0]}{axes[1]} plane"
    _label_view(ax, axes, view, plane)


def _path_panel(sub, axes, group, magnification):
    """The path views of runs that share ``axes``, into the subfigure ``sub``. A run whose magnified
    error would be over half the path's size (a diverged run) is drawn at true scale."""
    references = _references(group)
    span = _span(references or [_finite(t.run.result.position) for t in group])
    gain = magnification or _auto_magnification(group, references)
    gains = [gain if not np.nanmax(t.distance, initial=0.0) * gain > 0.5 * span else 1.0 for t in group]
    true_scale = [t.name for t, g in zip(group, gains) if g != gain]
    sub.suptitle(f"{', '.join(axes)}: contour error magnified {gain:g}x"
                 + (f"\nat true scale: {', '.join(true_scale)}" if true_scale else ""), fontsize=11)
    views = _path_views(len(axes))
    if not views:
        sub.add_subplot().text(0.5, 0.5, "a path needs two axes", ha="center", va="center")
    grid = (2, 2) if len(views) > 1 else (1, 1)
    for k, view in enumerate(views):
        _draw_path_view(_new_view(sub, (*grid, k + 1), view), group, axes, view, gains, span)


def draw_path(traces, magnification: float | None = None):
    """The reference path and each actual path with its contour error magnified; a circle marks each run's
    largest error. Runs of three axes: 3-D view and the xy, xz, yz projections; runs of another set of
    axes side by side."""
    from matplotlib.lines import Line2D
    groups = _axis_groups(traces)
    widths = [2.0 if len(axes) >= 3 else 1.1 for axes, _ in groups]
    height = 10.0 if max(widths) > 1.5 else 6.2
    fig = _figure("Path", 5.2 * sum(widths) + 0.6, height)
    subfigures = fig.subfigures(1, len(groups), width_ratios=widths, squeeze=False)[0]
    for sub, (axes, group) in zip(subfigures, groups):
        _path_panel(sub, axes, group, magnification)
    _run_legend(fig, traces, [Line2D([], [], color="black", lw=0.8, label="reference"),
                              Line2D([], [], ls="", marker="o", mfc="none", color="0.3", label="largest error")])
    return fig


def _error_norms(traces) -> list:
    """The colour scale of the runs' error maps [um], one for all of them so that one colour is one error in
    every panel (ILC passes, runs of a comparison): linear from 0 to the largest error where the runs' largest
    errors are within tenfold of each other, else logarithmic from a tenth of the smallest of the runs'
    largest errors (smaller errors take the lowest colour) to the largest (learning passes that improve a
    hundredfold, or a diverged run beside good ones, stay readable in every panel)."""
    from matplotlib.colors import LogNorm, Normalize
    finite = [t.distance[np.isfinite(t.distance)] for t in traces]
    worst = [float(np.max(d)) * 1e6 if len(d) else 0.0 for d in finite]
    top = [w for w in worst if w > 0.0] or [1.0]
    if max(top) <= 10.0 * min(top):
        shared = Normalize(0.0, max(top))
    else:
        shared = LogNorm(min(top) / 10.0, max(top), clip=True)
    return [shared] * len(traces)


def _coloured_segments(ax, points, values, norm):
    """A path of (m, d) points [mm] as segments coloured by ``values`` (per point) on ``norm``."""
    from matplotlib.collections import LineCollection
    segments = np.stack([points[:-1], points[1:]], axis=1)
    colours = 0.5 * (values[:-1] + values[1:])
    if points.shape[1] == 3:
        from mpl_toolkits.mplot3d.art3d import Line3DCollection
        ax.add_collection3d(Line3DCollection(segments, cmap=ERROR_MAP, norm=norm, array=colours, lw=2.2))
    else:
        ax.add_collection(LineCollection(segments, cmap=ERROR_MAP, norm=norm, array=colours, lw=2.2))


def _length(metres: float) -> str:
    """A contour error for a title: um, or mm from 1 mm up."""
    return f"{metres * 1e3:.3g} mm" if metres >= 1e-3 else f"{metres * 1e6:.3g} um"


def _error_map_panel(ax, trace, view, norm):
    position = _finite(trace.run.result.position)
    references = _references([trace])
    for ref in references:
        ax.plot(*(ref[:, i] * 1e3 for i in view), color="0.6", lw=0.6, ls="--")
    if len(position) > 1:
        _coloured_segments(ax, position[:, view] * 1e3, trace.distance * 1e6, norm)
    k = _worst_step(trace)
    if k is not None:
        ax.plot(*([position[k, i] * 1e3] for i in view), "o", ms=9, mfc="none", mew=1.5, color="red")
        note = f"largest: {_length(trace.distance[k])} at t = {trace.time[k]:.3g} s"
    else:
        note = "no steps recorded" if not len(position) else "no finite contour error"
    _view_limits(ax, view, references, [position], _span(references or [position]))
    _label_view(ax, trace.axes, view, None)
    ax.set_title(f"{trace.name}\n{note}", fontsize=10, color=trace.colour)


def draw_error_map(traces):
    """Each run's actual path coloured by its contour error magnitude (3-D for three axes)."""
    from matplotlib.cm import ScalarMappable
    columns = min(len(traces), 3)
    rows = -(-len(traces) // columns)
    fig = _figure("Contour error along the path", 5.4 * columns + 0.8, 4.9 * rows + 0.6)
    norms = _error_norms(traces)
    panels = []
    for k, (t, norm) in enumerate(zip(traces, norms)):
        view = (0, 1, 2) if len(t.axes) >= 3 else (0, 1)
        ax = _new_view(fig, (rows, columns, k + 1), view)
        _error_map_panel(ax, t, view, norm)
        panels.append(ax)
    log = " (logarithmic)" if type(norms[0]).__name__ == "LogNorm" else ""
    fig.colorbar(ScalarMappable(norms[0], ERROR_MAP), ax=panels, label=f"contour error [um]{log}", shrink=0.8)
    return fig


def draw_contour_error(traces):
    """The exact contour error against time and against the length travelled along the reference."""
    fig = _figure("Exact contour error", 8.5, 7.0)
    top, bottom = fig.subplots(2, 1)
    _series(top, traces, lambda t: t.time, lambda t: t.distance * 1e6)
    _style(top, "t [s]", "contour error [um]", "against time")
    _series(bottom, traces, lambda t: t.path_length * 1e3, lambda t: t.distance * 1e6)
    _style(bottom, "path length along the reference [mm]", "contour error [um]", "along the path")
    _run_legend(fig, traces)
    return fig


def _estimate(trace: _Trace) -> np.ndarray:
    return np.linalg.norm(_finite(trace.run.result.estimate_vector), axis=1)


def draw_estimate(traces):
    """The estimated contour error over the exact one, and their difference (log scale)."""
    from matplotlib.lines import Line2D
    fig = _figure("Estimated against exact contour error", 8.5, 7.0)
    top, bottom = fig.subplots(2, 1, sharex=True)
    _series(top, traces, lambda t: t.time, lambda t: t.distance * 1e6)
    _series(top, traces, lambda t: t.time, lambda t: _estimate(t) * 1e6, suffix=" estimate", ls="--")
    _style(top, "", "contour error [um]", "exact (solid) and estimate (dashed)")
    deviation = {id(t): np.abs(_estimate(t) - t.distance) * 1e6 for t in traces}
    _series(bottom, traces, lambda t: t.time, lambda t: deviation[id(t)])
    if any(np.nanmax(d, initial=0.0) > 0.0 for d in deviation.values() if np.isfinite(d).any()):
        bottom.set_yscale("log", nonpositive="mask")
    _style(bottom, "t [s]", "|estimate - exact| [um]", "estimation error")
    _run_legend(fig, traces, [Line2D([], [], color="0.3", label="exact"),
                              Line2D([], [], color="0.3", ls="--", label="estimate")])
    return fig


def _per_axis_figure(traces, title: str, columns: list):
    """Rows per axis name (a run is drawn in the rows of its own axes), a column per signal; ``columns``
    holds (heading, y label with {axis}, signal(trace, axis index))."""
    axes = _axis_union(traces)
    fig = _figure(title, 5.0 * len(columns) + 1.5, 2.3 * len(axes) + 1.4)
    panels = fig.subplots(len(axes), len(columns), sharex=True, squeeze=False)
    for r, axis in enumerate(axes):
        for c, (heading, ylabel, signal) in enumerate(columns):
            owners = [t for t in traces if axis in t.axes]
            _series(panels[r, c], owners, lambda t: t.time,
                    lambda t, signal=signal, axis=axis: signal(t, t.axes.index(axis)), signed=True)
            _style(panels[r, c], "t [s]" if r == len(axes) - 1 else "", ylabel.format(axis=axis),
                   heading if r == 0 else None)
    _run_legend(fig, traces)
    return fig


def _tracking_error(trace: _Trace, i: int) -> np.ndarray:
    """R_i - P_i of axis i [um]."""
    return (trace.run.result.reference_position[:, i] - trace.run.result.position[:, i]) * 1e6


def draw_tracking(traces):
    """Each axis' tracking error R_i - P_i."""
    return _per_axis_figure(traces, "Axis tracking error",
                            [("tracking error R - P", "{axis} tracking error [um]", _tracking_error)])


def draw_effort(traces):
    """Each axis' actuator command, and the cross-coupled correction in it on an axis of its own."""
    return _per_axis_figure(traces, "Actuator command and cross-coupled correction", [
        ("actuator command", "u_{axis} [command units]", lambda t, i: t.run.result.command[:, i]),
        ("CCC correction (part of the command)", "c_{axis} [command units]",
         lambda t, i: t.run.result.correction[:, i])])


def _block_limits(trace: _Trace, override: float | None = None) -> np.ndarray:
    """The feed limit [m/s] of each block of a tool path run: the feed plan's (F, rapid rate, axes,
    centripetal or contour-tolerance bound; under another feed ``override`` where given), else the programmed
    F (nan where there is none)."""
    try:
        schedule = build_schedule(trace.experiment, trace.curve)
        if override is not None and hasattr(schedule, "rest_of_path"):
            schedule = schedule.rest_of_path(trace.curve.domain[0], override)
    except ContouringError:
        schedule = None
    limits = getattr(schedule, "limits", None)
    if limits is not None:
        return np.array([limit.feed for limit in limits])
    return np.array([np.nan if b.feed is None else b.feed for b in trace.curve.blocks])


def _block_of(trace: _Trace) -> np.ndarray:
    starts = np.array([b.start for b in trace.curve.blocks])
    theta = _finite(trace.run.result.theta)
    return np.clip(np.searchsorted(starts, np.nan_to_num(theta), side="right") - 1, 0, len(starts) - 1)


#: feed.png labels every block up to this many, beyond it at most this many ticks along the blocks
LABELLED_BLOCKS = 40


def _feed_events(trace) -> list:
    """(step, label) of the run's feed holds and overrides (its experiment's ``feed_events``) and of a monitoring
    breach."""
    experiment = trace.experiment
    if experiment is None:
        return []
    ts = experiment.sample_time
    out = [(step, f"hold {step * ts:g} s" if what == "hold" else f"{value * 100:g}% {step * ts:g} s")
           for step, what, value in parse_feed_events(experiment.feed_events, ts) if what != "resume"]
    breach = breach_of(trace.run.result, experiment)
    if breach is not None:
        out.append((breach.step, f"breach {breach.step * ts:g} s"))
    return out


def _override_stretches(trace) -> list:
    """((start, end) arc length [m], feed override or None for the plan's own) of each stretch of the path a
    run went along under one feed override (its experiment's ``feed_events``; 0 % left out: no feed there)."""
    theta, domain = _finite(trace.run.result.theta), trace.curve.domain
    experiment, out, at, current = trace.experiment, [], domain[0], None
    events = parse_feed_events(experiment.feed_events, experiment.sample_time) if experiment is not None else []
    for step, what, value in events:
        if what != "override" or value == 0.0 or step >= len(theta):
            continue
        here = float(theta[step])
        out.append(((at, here), current))
        at, current = here, value
    return out + [((at, domain[1]), current)]


def draw_feed(traces):
    """Tool path runs: the feed along the path against each block's limit, in the program's unit per minute
    (:func:`contouring_ros.records.blocks.feed_unit`), and the largest contour error of each block (labelled by its
    source line; with more than :data:`LABELLED_BLOCKS` blocks, by some of them, drawn as a line)."""
    from matplotlib.lines import Line2D
    from matplotlib.ticker import MaxNLocator
    paths = [t for t in traces if isinstance(t.curve, ToolPath)]
    fig = _figure("Feed and contour error per block", 9.5, 7.6)
    top, bottom = fig.subplots(2, 1)
    width = 0.8 / max(len(paths), 1)
    labels, unit = [], "mm/min"
    for k, t in enumerate(paths):
        blocks = t.curve.blocks
        per_minute, unit = feed_unit(t.curve)          # metres per unit of the program
        scale = 60.0 / per_minute
        feed = np.linalg.norm(_finite(t.run.result.reference_velocity), axis=1)
        top.plot(_finite(t.run.result.theta) / per_minute, feed * scale, color=t.colour, lw=1.2)
        edges = np.array([b.start for b in blocks] + [t.curve.domain[1]]) / per_minute
        for (start, end), override in _override_stretches(t):      # each stretch under its feed override
            start, end = start / per_minute, end / per_minute
            inside = np.flatnonzero((edges[1:] > start) & (edges[:-1] < end))
            if inside.size:
                top.stairs((_block_limits(t, override) * scale)[inside],
                           np.clip(edges[inside[0]:inside[-1] + 2], start, end), color=t.colour, ls="--", lw=0.9,
                           baseline=None)
        if len(blocks) <= LABELLED_BLOCKS:
            for edge in edges[1:-1]:
                top.axvline(edge, color="0.85", lw=0.6, zorder=0)
        for step, label in _feed_events(t):          # holds, overrides and a breach, where they came
            at = float(_finite(t.run.result.theta)[min(step, len(t.run.result.theta) - 1)]) / per_minute
            top.axvline(at, color=t.colour, ls=":", lw=1.0)
            top.annotate(label, (at, 1.0), xycoords=("data", "axes fraction"), rotation=90, fontsize=7,
                         va="top", ha="right", color=t.colour)
        lines = list(dict.fromkeys(b.line for b in blocks))            # source blocks (a blend arc: its line's)
        source = np.searchsorted(lines, [b.line for b in blocks]) if lines == sorted(lines) else \
            np.array([lines.index(b.line) for b in blocks])
        of_step = source[_block_of(t)]
        worst = np.array([np.nanmax(t.distance[of_step == i], initial=np.nan) if np.any(of_step == i) else np.nan
                          for i in range(len(lines))]) * 1e6
        if len(lines) <= LABELLED_BLOCKS:
            positions = np.arange(len(lines)) + (k - (len(paths) - 1) / 2) * width
            bottom.bar(positions, np.nan_to_num(worst), width=width, color=t.colour)
        else:
            bottom.step(np.arange(len(lines)), np.nan_to_num(worst), where="mid", color=t.colour, lw=0.9)
        if len(lines) > len(labels):
            codes = dict(zip([b.line for b in blocks], block_codes(t.curve)))
            labels = [(line, codes[line]) for line in lines]
    path_unit = "in" if unit == "in/min" else "mm"
    _style(top, f"path length [{path_unit}]", f"feed [{unit}]",
           "feed along the path (solid) and each block's limit (dashed)")
    if len(labels) <= LABELLED_BLOCKS:
        bottom.set_xticks(np.arange(len(labels)), [f"line {line}\n{code}" for line, code in labels],
                          fontsize=8 if len(labels) <= 16 else 6, rotation=0 if len(labels) <= 16 else 90)
    else:
        bottom.xaxis.set_major_locator(MaxNLocator(12, integer=True))
        bottom.set_xlim(-0.5, len(labels) - 0.5)
        bottom.set_xticks([i for i in bottom.get_xticks() if 0 <= i < len(labels)])
        bottom.set_xticklabels([f"line {labels[int(i)][0]}" for i in bottom.get_xticks()], fontsize=8)
    _style(bottom, "block (by its source line)", "largest contour error [um]", "contour error per block")
    _run_legend(fig, paths, [Line2D([], [], color="0.3", label="feed"),
                             Line2D([], [], color="0.3", ls="--", label="feed limit")])
    return fig


def _draw_all(traces, magnification=None) -> dict:
    with np.errstate(all="ignore"):
        drawn = {"path": draw_path(traces, magnification), "error_map": draw_error_map(traces),
                 "contour_error": draw_contour_error(traces), "estimate": draw_estimate(traces),
                 "tracking": draw_tracking(traces), "effort": draw_effort(traces)}
        if any(isinstance(t.curve, ToolPath) for t in traces):
            drawn["feed"] = draw_feed(traces)
        return drawn


def figures(runs: list, magnification: float | None = None) -> dict:
    """Matplotlib figures of one run or a comparison: name -> Figure.

    ``runs`` is a list of (label, RecordedRun); legends name each run by the experiment name stored in its
    bag (the label where there is none), and a run has the same colour in every figure. Runs of different
    axes (2 and 3) may be compared. Figures: ``path`` (error magnified; 3-D and projections for three
    axes), ``error_map`` (path coloured by contour error), ``contour_error`` (against time and path
    length), ``estimate`` (estimate against exact), ``tracking`` and ``effort`` (per axis; the CCC
    correction on its own axes); for tool paths also ``feed`` (feed along the path against each block's
    limit, and the contour error per block).
    """
    return _draw_all(_traces(runs), magnification)


def write_figures(runs: list, directory, magnification: float | None = None, drawn: dict | None = None) -> list:
    """Write :func:`figures` (or ``drawn``, those figures already drawn) as PNG files into ``directory``;
    returns their paths."""
    directory = Path(directory)
    if directory.exists() and not directory.is_dir():
        raise OutputError(f"{directory}: a file of that name exists; the figures are written into a folder "
                          "(name another with --out)")
    paths = []
    for name, fig in (drawn if drawn is not None else figures(runs, magnification)).items():
        png = _png(fig)
        paths.append(write_atomically(directory / f"{name}.png", lambda tmp: tmp.write_bytes(png)))
    return paths


_RENDERED = weakref.WeakKeyDictionary()     # figure -> its PNG, so that files and report render it once


def _png(fig) -> bytes:
    """A figure as PNG bytes (rendered once per figure)."""
    if fig not in _RENDERED:
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png", dpi=FIGURE_DPI)
        _RENDERED[fig] = buffer.getvalue()
    return _RENDERED[fig]


# --- HTML report -------------------------------------------------------------------------------------

CAPTIONS = {
    "path": "Reference path (black) and each run's actual path with its contour error magnified by the factor "
            "in the panel title; a circle marks each run's largest contour error. Runs of three axes: 3-D "
            "view and the xy, xz and yz projections.",
    "error_map": "Each run's actual path coloured by the magnitude of its exact contour error; a red circle "
                 "marks the largest.",
    "contour_error": "Exact contour error (distance from the actual position to the whole reference curve) "
                     "against time and against the length travelled along the reference.",
    "estimate": "The contour error estimate the controller used (dashed) over the exact contour error (solid), "
                "and the magnitude of their difference.",
    "tracking": "Each axis' tracking error R - P.",
    "effort": "Each axis' actuator command, and the cross-coupled (CCC) correction in it on an axis of its own.",
}

_STYLE = """
body{font-family:system-ui,sans-serif;max-width:84em;margin:1.5em auto;padding:0 1em;color:#222}
h1{font-size:1.6em;margin-bottom:.2em} h2{border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:1.6em}
table{border-collapse:collapse;margin:.6em 0;font-size:.92em}
th,td{border:1px solid #d0d0d0;padding:.25em .6em} th{background:#f3f3f3;text-align:left}
td.num{text-align:right;font-variant-numeric:tabular-nums} td.better{background:#e3f4e3}
td.worse{background:#f8e1e1} td.base{color:#888}
.swatch{display:inline-block;width:1.6em;height:.35em;vertical-align:middle;margin-right:.4em;border-radius:2px}
figure{margin:1em 0} figure img{max-width:100%;border:1px solid #e5e5e5} figcaption{color:#555;font-size:.9em}
pre{background:#f7f7f7;padding:.8em;overflow-x:auto;font-size:.85em} details{margin:.4em 0}
summary{cursor:pointer} .warning{color:#a33} .scroll{overflow-x:auto} td.wide{min-width:22em}
th .swatch{display:block;margin:0 0 .25em 0}
"""


def _score_rows(axes: list) -> list:
    """(label, value(scores, run axes)) of every score, the per-axis ones by axis name (None for a run
    without that axis)."""
    def per_axis(field, axis, scale):
        return lambda s, own: getattr(s, field)[own.index(axis)] * scale if axis in own else None
    rows = [(label, lambda s, own, get=get: get(s)) for label, get in SCORE_ROWS]
    for axis in axes:
        rows += [(f"tracking error max {axis} [um]", per_axis("tracking_max", axis, 1e6)),
                 (f"tracking error RMS {axis} [um]", per_axis("tracking_rms", axis, 1e6))]
    rows += [(f"effort RMS {axis} [command units]", per_axis("effort_rms", axis, 1.0)) for axis in axes]
    return rows + [("travel time [s]", lambda s, own: s.travel_time), ("steps", lambda s, own: s.steps)]


def _number(value) -> str:
    if value is None:
        return "-"
    return f"{value:d}" if isinstance(value, (int, np.integer)) else f"{value:.4g}"


def _run_header(traces) -> str:
    return "<tr><th>metric</th>" + "".join(
        f'<th><span class="swatch" style="background:{t.colour}"></span>{html.escape(t.name)}</th>'
        for t in traces) + "</tr>"


def _html_scores(traces, scores) -> str:
    """The scores of every run as an HTML table."""
    rows = []
    for label, value in _score_rows(_axis_union(traces)):
        cells = "".join(f'<td class="num">{_number(value(s, t.axes) if s is not None else None)}</td>'
                        for t, s in zip(traces, scores))
        rows.append(f"<tr><td>{html.escape(label)}</td>{cells}</tr>")
    return f'<h2>Scores</h2><div class="scroll"><table>{_run_header(traces)}{"".join(rows)}</table></div>'


def _ratio_cell(value, reference, is_baseline: bool) -> str:
    if value is None or reference is None or not reference or not np.isfinite(reference):
        return '<td class="num">-</td>'
    ratio = value / reference
    kind = "base" if is_baseline else "better" if ratio < 0.95 else "worse" if ratio > 1.05 else ""
    return f'<td class="num {kind}">{ratio:.3g}</td>'


def _html_ratios(traces, scores, baseline: int) -> str:
    """Each run's main metrics as a ratio to the baseline run's (those of ``compare_table``)."""
    if scores[baseline] is None:
        return "<h2>Ratios</h2><p>The baseline run has no scores.</p>"
    rows = []
    for label, get in SCORE_ROWS:
        reference = get(scores[baseline])
        cells = "".join(_ratio_cell(get(s) if s is not None else None, reference, k == baseline)
                        for k, s in enumerate(scores))
        rows.append(f"<tr><td>{html.escape(label.split(' [')[0])}</td>{cells}</tr>")
    return (f"<h2>Ratios to {html.escape(traces[baseline].name)}</h2><p>Below 1: smaller than the baseline's "
            f'(green); above 1: larger (red).</p><div class="scroll"><table>{_run_header(traces)}{"".join(rows)}'
            "</table></div>")


def _kind(experiment, section: str) -> str:
    """The type of an experiment's section (curve, estimator, controller), for the runs table."""
    part = getattr(experiment, section, None) if experiment is not None else None
    return html.escape(str(part.get("type", "-"))) if part else "-"


def _html_runs(traces, runs) -> str:
    """One row per run: colour, name, bag, axes, steps, curve, estimator, controller, description."""
    rows = []
    for t, (label, run) in zip(traces, runs):
        kinds = "".join(f"<td>{_kind(t.experiment, section)}</td>" for section in ("curve", "estimator", "controller"))
        description = (t.experiment.info.get("experiment") or {}).get("description", "") if t.experiment else ""
        rows.append(f'<tr><td><span class="swatch" style="background:{t.colour}"></span>{html.escape(t.name)}'
                    f"</td><td>{html.escape(label)}</td><td>{', '.join(map(html.escape, t.axes))}</td>"
                    f'<td class="num">{run.complete_steps}</td>'
                    f"{kinds}"
                    f'<td class="wide">{html.escape(str(description))}</td></tr>')
    warnings = "".join(f'<p class="warning"><b>warning</b> ({html.escape(t.name)}): {html.escape(w)}</p>'
                       for t, (_, run) in zip(traces, runs) for w in run.warnings)
    return ('<h2>Runs</h2><div class="scroll"><table><tr><th>run</th><th>bag</th><th>axes</th><th>steps</th>'
            "<th>curve</th><th>estimator</th><th>CCC</th><th>description</th></tr>"
            f"{''.join(rows)}</table></div>{warnings}")


def _png_base64(fig) -> str:
    return base64.b64encode(_png(fig)).decode()


def _html_figures(drawn: dict) -> str:
    return "<h2>Figures</h2>" + "".join(
        f'<figure id="{name}"><img alt="{name}" src="data:image/png;base64,{_png_base64(fig)}">'
        f"<figcaption>{html.escape(CAPTIONS.get(name, name))}</figcaption></figure>" for name, fig in drawn.items())


def _html_differences(traces, runs) -> str:
    """A table of the experiment keys whose values differ between the compared runs (nothing for one run)."""
    if len(runs) < 2:
        return ""
    changed = experiment_differences(runs)
    if not changed:
        return "<h2>Differences</h2><p>The experiments differ in nothing but their names.</p>"
    rows = "".join(f"<tr><td><code>{html.escape(key)}</code></td>"
                   + "".join(f"<td>{html.escape('-' if value is None else str(value))}</td>" for value in values)
                   + "</tr>" for key, values in changed.items())
    return ('<h2>Differences</h2><p>The experiment keys whose values differ between the runs (grid keys, as '
            '<code>--set</code> and sweeps name them).</p><div class="scroll"><table><tr><th>key</th>'
            + "".join(f'<th><span class="swatch" style="background:{t.colour}"></span>{html.escape(t.name)}</th>'
                      for t in traces) + f"</tr>{rows}</table></div>")


def _html_experiments(traces) -> str:
    return "<h2>Experiments</h2>" + "".join(
        f"<details><summary>{html.escape(t.name)}: experiment YAML</summary>"
        f"<pre>{html.escape(t.run.experiment_text)}</pre></details>" for t in traces)


def _html_blocks(traces) -> str:
    """For tool path runs: the scores of the cutting moves alone and the results per block
    (:mod:`contouring_ros.records.blocks`)."""
    parts = []
    for t in traces:
        if t.curve is None or not hasattr(t.curve, "blocks") or t.experiment is None or t.diverged:
            continue
        try:
            schedule = build_schedule(t.experiment, t.curve)
        except ContouringError:
            schedule = None
        tolerance = t.experiment.schedule.get("contour_tolerance") or 0.0
        end = motion_steps(t.curve, t.run.result, t.experiment)
        rows = block_results(t.curve, t.run.result, schedule, tolerance, end=end)
        cutting = cutting_scores(t.curve, t.run.result, end)
        head = block_headings(t.axes, t.curve)
        body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in block_cells(
            r, t.curve, t.experiment.sample_time)) + "</tr>" for r in rows)
        summary = "" if cutting is None else (
            f"<p>Cutting moves (G1/G2/G3; start-up and rapids left out, {cutting.steps} steps): MCE "
            f"{cutting.mce * 1e6:.4g} um, TACE {cutting.tace * 1e6:.4g} um, RMS {cutting.rms * 1e6:.4g} um.</p>")
        parts.append(f"<h3>{html.escape(t.name)}</h3>{summary}<div class=\"scroll\"><table><tr>"
                     + "".join(f"<th>{html.escape(h)}</th>" for h in head) + f"</tr>{body}</table></div>")
    return "<h2>Per block</h2>" + "".join(parts) if parts else ""


def html_report(runs: list, scores: list, path, magnification: float | None = None, baseline: int = 0,
                drawn: dict | None = None) -> Path:
    """A self-contained HTML page of one run or a comparison: the runs, their scores and the ratios to the
    ``baseline`` run as tables, for tool path runs the scores of the cutting moves and the results per
    block, every figure (embedded PNG; ``drawn``: the :func:`figures` of these runs, when already drawn)
    and each run's experiment YAML (collapsible); for a comparison, the experiment keys whose values
    differ between the runs. ``scores`` holds a Scores or None
    (not scored) per run."""
    traces = _traces(runs)
    drawn = drawn if drawn is not None else _draw_all(traces, magnification)
    title = "Contouring report: " + (" vs ".join(t.name for t in traces) if len(traces) <= 2 else
                                      f"{traces[0].name} and {len(traces) - 1} other runs")
    page = (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{_STYLE}</style></head><body><h1>{html.escape(title)}</h1>"
            f"{_html_runs(traces, runs)}{_html_differences(traces, runs)}"
            f"{_html_scores(traces, scores)}{_html_ratios(traces, scores, baseline)}"
            f"{_html_blocks(traces)}{_html_figures(drawn)}{_html_experiments(traces)}</body></html>")
    return write_atomically(path, lambda tmp: tmp.write_text(page))
