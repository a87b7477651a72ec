"""Figures of one recorded run or a comparison of runs, drawn with matplotlib from their traces
(:mod:`contouring_ros.records.traces`): the path with its contour error magnified, the path coloured by the error,
the contour error against time and path length, the estimate against the exact error, each axis' tracking error
and effort and, for tool paths, the feed and contour error per block; written as PNG files.

Units: paths in mm, errors in um, time in s, actuator signals in the command's units. Non-finite samples (a
diverged run) are gaps. Figures are drawn on the Agg canvas, outside pyplot.
"""
from __future__ import annotations

import io
import weakref
from pathlib import Path

import numpy as np

from .blocks import block_codes, feed_unit
from ..experiment.build import build_schedule
from ..core.curves import ToolPath
from ..errors import ContouringError, OutputError
from .outputs import write_atomically
from ..core.feed_control import parse_feed_events
from .scoring import breach_of
from .traces import (Trace, auto_magnification, axis_groups, axis_union, finite_or_nan, magnified, path_span,
                     reference_paths, traces_of, worst_step)

__all__ = ["ERROR_MAP", "DIVERGED", "FIGURE_DPI", "LABELLED_BLOCKS", "draw_path", "draw_error_map",
           "draw_contour_error", "draw_estimate", "draw_tracking", "draw_effort", "draw_feed", "draw_all", "figures",
           "write_figures", "png_bytes"]

ERROR_MAP = "viridis"         # the colour map of the error maps
DIVERGED = "diverged"         # the gid of a diverged run's lines
FIGURE_DPI = 130              # of the PNG files and the report's images


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
        ax.plot(finite_or_nan(x(t)), finite_or_nan(y(t)), color=t.colour, label=t.name + suffix,
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
    references = reference_paths(group)
    for ref in references:
        ax.plot(*(ref[:, i] * 1e3 for i in view), color="black", lw=0.8)
    paths = []
    for t, gain in zip(group, gains):
        shown = magnified(t, gain)
        paths.append(shown)
        ax.plot(*(shown[:, i] * 1e3 for i in view), color=t.colour, lw=1.2, label=t.name)
        k = worst_step(t)
        if k is not None:
            ax.plot(*([shown[k, i] * 1e3] for i in view), "o", ms=8, mfc="none", mew=1.5, color=t.colour)
    _view_limits(ax, view, references, paths, span)
    plane = "3-D path" if len(view) == 3 else f"{axes[view[0]]}{axes[view[1]]} projection" if len(axes) > 2 \
        else f"{axes[0]}{axes[1]} plane"
    _label_view(ax, axes, view, plane)


def _path_panel(sub, axes, group, magnification):
    """The path views of runs that share ``axes``, into the subfigure ``sub``. A run whose magnified
    error would be over half the path's size (a diverged run) is drawn at true scale."""
    references = reference_paths(group)
    span = path_span(references or [finite_or_nan(t.run.result.position) for t in group])
    gain = magnification or auto_magnification(group, references)
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
    groups = axis_groups(traces)
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
    position = finite_or_nan(trace.run.result.position)
    references = reference_paths([trace])
    for ref in references:
        ax.plot(*(ref[:, i] * 1e3 for i in view), color="0.6", lw=0.6, ls="--")
    if len(position) > 1:
        _coloured_segments(ax, position[:, view] * 1e3, trace.distance * 1e6, norm)
    k = worst_step(trace)
    if k is not None:
        ax.plot(*([position[k, i] * 1e3] for i in view), "o", ms=9, mfc="none", mew=1.5, color="red")
        note = f"largest: {_length(trace.distance[k])} at t = {trace.time[k]:.3g} s"
    else:
        note = "no steps recorded" if not len(position) else "no finite contour error"
    _view_limits(ax, view, references, [position], path_span(references or [position]))
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


def _estimate(trace: Trace) -> np.ndarray:
    return np.linalg.norm(finite_or_nan(trace.run.result.estimate_vector), axis=1)


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
    axes = axis_union(traces)
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


def _tracking_error(trace: Trace, i: int) -> np.ndarray:
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


def _block_limits(trace: Trace, override: float | None = None) -> np.ndarray:
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
    return np.array(trace.curve.blocks.column("feed"))


def _block_of(trace: Trace) -> np.ndarray:
    starts = np.array(trace.curve.blocks.column("start"))
    theta = finite_or_nan(trace.run.result.theta)
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
    theta, domain = finite_or_nan(trace.run.result.theta), trace.curve.domain
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
        feed = np.linalg.norm(finite_or_nan(t.run.result.reference_velocity), axis=1)
        top.plot(finite_or_nan(t.run.result.theta) / per_minute, feed * scale, color=t.colour, lw=1.2)
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
            at = float(finite_or_nan(t.run.result.theta)[min(step, len(t.run.result.theta) - 1)]) / per_minute
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


def draw_all(traces, magnification=None) -> dict:
    """Every figure of :func:`figures`, drawn from ``traces`` (:func:`contouring_ros.records.traces.traces_of`)."""
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
    return draw_all(traces_of(runs), magnification)


def write_figures(runs: list, directory, magnification: float | None = None, drawn: dict | None = None) -> list:
    """Write :func:`figures` (or ``drawn``, those figures already drawn) as PNG files into ``directory``;
    returns their paths."""
    directory = Path(directory)
    if directory.exists() and not directory.is_dir():
        raise OutputError(f"{directory}: a file of that name exists; the figures are written into a folder "
                          "(name another with --out)")
    paths = []
    for name, fig in (drawn if drawn is not None else figures(runs, magnification)).items():
        png = png_bytes(fig)
        paths.append(write_atomically(directory / f"{name}.png", lambda tmp: tmp.write_bytes(png)))
    return paths


_RENDERED = weakref.WeakKeyDictionary()     # figure -> its PNG, so that files and report render it once


def png_bytes(fig) -> bytes:
    """A figure as PNG bytes (rendered once per figure)."""
    if fig not in _RENDERED:
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png", dpi=FIGURE_DPI)
        _RENDERED[fig] = buffer.getvalue()
    return _RENDERED[fig]
