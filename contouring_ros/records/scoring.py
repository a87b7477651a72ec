"""Scoring of runs (bags or in-process results) and their tables; reading a bag as a run whose experiment is
parsed once (:func:`read_run`)."""
from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from . import bag, bag_reader
from .bag import RecordedRun
from .blocks import breach_line, cutting_scores, motion_end
from .numbers import number
from ..core.monitoring import first_breach
from ..experiment.build import build_curve, build_schedule, in_position_windows, monitoring_limits
from ..experiment.validate import parse_experiment
from ..core.geometry import ExactContourError
from ..core.metrics import Scores, score
from ..core.simulation import path_bound
from ..errors import BagError, ConfigError, ContouringError, ScoreError

__all__ = ["read_run", "score_run", "score_bag", "check_experiment_matches", "curve_of", "format_scores",
           "format_realtime", "miss_rate", "tolerance_line", "cutting_lines", "motion_steps", "breach_of", "breach_message", "SCORE_ROWS",
           "BAG_EXPERIMENT", "scores_lines", "recorded_lines", "json_scores"]

#: the name a bag's experiment goes by in messages (its ``where``)
BAG_EXPERIMENT = "the bag's experiment"

REALTIME_COLUMNS = ("ticks", "deadline misses", "skipped ticks", "late inputs", "ticks missing an input",
                    "latency p50 [us]", "latency p99 [us]", "latency max [us]", "work p50 [us]", "work p99 [us]",
                    "jitter [us]")


def read_run(path, keep_payloads: bool = False, experiment_text: str | None = None, progress: bool = False,
             parsed=None) -> RecordedRun:
    """A bag as a run (:func:`contouring_ros.records.bag.read_contents`, then :func:`~contouring_ros.records.bag.decode_run`)
    whose experiment text is parsed here, once, and carried by the run (``experiment``).

    ``experiment_text`` is the experiment's YAML for a bag recorded without one (it replaces the stored one);
    ``parsed`` an Experiment this process has parsed already (the one it just ran, or the one given for the
    bag), used as is where its text is the run's, instead of parsing that text again. An experiment that
    does not validate here (e.g. a part program it names is not on this machine) is a warning, and the run
    is read without it. Whatever the file holds, what cannot be read is a BagError of one line.
    """
    path = Path(path)
    with bag.reading(path):
        contents = bag.read_contents(path, keep_payloads, experiment_text, progress)
        experiment, error = _experiment_of(contents, parsed)
        return bag.decode_run(contents, experiment, _divergence_bound(experiment), error)


def _experiment_of(contents, parsed) -> tuple:
    """(Experiment, None) of the text a bag's contents use: ``parsed`` where that is its text, else the text
    parsed; (None, the error) with a warning where it does not validate here."""
    if parsed is not None and parsed.text == contents.experiment_text:
        return replace(parsed, path=BAG_EXPERIMENT), None
    try:
        return parse_experiment(contents.experiment_text, BAG_EXPERIMENT), None
    except (ConfigError, ValueError, OSError) as error:
        contents.warnings.append(f"{contents.path}: its experiment does not validate here ({error}); read without it")
        return None, error


def _divergence_bound(experiment) -> float | None:
    """The bound of the experiment's whole path (as the simulation checks it); None (the recorded
    reference's own size) without an experiment or where it cannot be built."""
    if experiment is None:
        return None
    try:
        curve = build_curve(experiment)
        return path_bound(curve, build_schedule(experiment, curve), experiment.divergence_factor)
    except (ContouringError, ValueError, ArithmeticError):
        return None


def motion_steps(curve, result, experiment=None) -> int:
    """How many steps of ``result`` its motion takes (:func:`contouring_ros.records.blocks.motion_end`; every step for
    a curve that is not a tool path), with the ``experiment``'s in-position windows and timeout where it has
    them (without an experiment: up to the step at which the reference comes to rest at the path's end)."""
    windows = in_position_windows(experiment) if experiment is not None else None
    timeout = (experiment.schedule.get("in_position_timeout") or math.inf) if windows is not None else math.inf
    stopped = experiment is not None and breach_of(result, experiment) is not None
    return motion_end(curve, result, windows, timeout, stopped)


def breach_of(result, experiment):
    """The first monitoring breach of a run (:func:`contouring_ros.core.monitoring.first_breach` with the
    experiment's ``contour_error_limit`` and ``following_error_limit``; the test the run applied as it ran, so
    a bag tells what its interpolator did), or None."""
    limits = monitoring_limits(experiment)
    return None if limits is None else first_breach(result, *limits)


def breach_message(curve, result, experiment) -> str | None:
    """One line for a run that monitoring stopped: the breach (:func:`contouring_ros.records.blocks.breach_line`) and
    where the reference came to rest; None for a run without a breach."""
    breach = breach_of(result, experiment)
    if breach is None:
        return None
    end = motion_steps(curve, result, experiment)
    return (f"{breach_line(breach, curve, list(experiment.axes), experiment.sample_time)}; stopped on the path at "
            f"{float(result.theta[end - 1]) * 1e3:.3f} mm of {curve.domain[1] * 1e3:.3f} mm, "
            f"t = {float(result.time[end - 1]):g} s")


def score_run(curve, run, from_time: float = 0.0, experiment=None) -> Scores:
    """Scores of a SimulationResult on ``curve``; with ``from_time`` only of its samples at t >= from_time
    (steady state). A run with no such sample is refused with a ScoreError. On a tool path only the steps
    of the motion count (:func:`motion_steps` with the ``experiment``'s in-position check): the travel time
    ends when the last motion has ended and its axes are in position, not with the reserve after it."""
    end = motion_steps(curve, run, experiment)
    try:
        return score(curve, run.time[:end], run.position[:end], run.reference_position[:end],
                     run.estimate_vector[:end], run.command[:end], theta=run.theta[:end], from_time=from_time)[0]
    except ValueError as error:
        raise ScoreError(f"--from {from_time:g}: {error}") from None


def tolerance_line(schedule: dict, mce: float) -> str | None:
    """Whether a run held its schedule's ``contour_tolerance`` (the contour-tolerance planner's bound): one line
    with the MCE, and by how much it exceeded the bound if it did; None without a tolerance."""
    tolerance = schedule.get("contour_tolerance") or 0.0
    if not tolerance:
        return None
    verdict = "held" if mce <= tolerance else f"exceeded by {(mce - tolerance) * 1e6:.4g} um " \
                                              f"({mce / tolerance:.3g} x)"
    return f"contour tolerance {tolerance * 1e6:.4g} um: {verdict} (MCE {mce * 1e6:.4g} um)"


def cutting_lines(curve, result, experiment) -> list:
    """For a tool path run: one line with the scores of its cutting moves alone (G1 / G2 / G3, the start-up,
    rapids and the reserve after the motion left out: :mod:`contouring_ros.records.blocks`), then the
    contour-tolerance verdict on them (where the ``experiment``'s schedule has a tolerance); for any other run
    the verdict on the whole run, if any."""
    schedule = experiment.schedule
    cutting = cutting_scores(curve, result, motion_steps(curve, result, experiment))
    if cutting is None:
        held = tolerance_line(schedule, score_run(curve, result).mce) if schedule.get("contour_tolerance") else None
        return [held] if held else []
    lines = [f"cutting moves (G1/G2/G3; start-up and rapids left out, {cutting.steps} steps): MCE "
             f"{cutting.mce * 1e6:.4g} um, TACE {cutting.tace * 1e6:.4g} um, RMS {cutting.rms * 1e6:.4g} um"]
    held = tolerance_line(schedule, cutting.mce)
    return lines + ([held] if held else [])


def score_bag(path, experiment_text: str | None = None, progress: bool = False,
              from_time: float = 0.0, parsed=None) -> tuple[Scores, RecordedRun]:
    """Score a bag from its contents alone: the curve comes from the experiment stored in it (or from
    ``experiment_text`` for a bag recorded without one); ``from_time`` as in :func:`score_run`, ``parsed``
    as in :func:`read_run`."""
    run = read_run(path, experiment_text=experiment_text, progress=progress, parsed=parsed)
    curve = curve_of(run)
    if experiment_text is not None:
        check_experiment_matches(run, curve, path)
    return score_run(curve, run.result, from_time, run.experiment), run


def check_experiment_matches(run: RecordedRun, curve, path) -> None:
    """Refuse (BagError, one line) an experiment given for a bag that it did not produce: other axes, or a
    curve the recorded /reference does not lie on (checked at up to 200 steps spread over the run, to within
    1e-9 of the path's size + 1 nm)."""
    experiment = replace(run.require_experiment(), path="--experiment")     # named as the option names it
    if list(experiment.axes) != list(run.axes):
        raise BagError(f"{path}: --experiment {experiment.name} has axes {', '.join(experiment.axes)}; the bag "
                       f"has {', '.join(run.axes)}")
    reference = run.result.reference_position
    rows = np.unique(np.linspace(0, len(reference) - 1, min(200, len(reference))).astype(int))
    distance = ExactContourError(curve, window=0.0)(reference[rows]).distance
    size = float(np.max(np.ptp(reference, axis=0))) if len(reference) > 1 else 0.0
    worst = int(np.argmax(distance))
    if distance[worst] > 1e-9 * size + 1e-9:
        raise BagError(f"{path}: the bag's /reference is not on the curve of --experiment {experiment.name} "
                       f"({distance[worst] * 1e6:.4g} um off at t = {run.result.time[rows[worst]]:g} s): it was "
                       "recorded from another experiment")


def curve_of(run: RecordedRun):
    """The reference curve of a recorded run, built from the experiment it carries."""
    return build_curve(run.require_experiment())


#: (label, value of a Scores) of the contour rows every score table starts with (:func:`format_scores`, the
#: comparison tables of :mod:`contouring_ros.records.comparison` and :mod:`contouring_ros.records.html_report`)
SCORE_ROWS = [("MCE [um]", lambda s: s.mce * 1e6), ("TACE [um]", lambda s: s.tace * 1e6),
              ("RMS contour error [um]", lambda s: s.rms * 1e6),
              ("estimation deviation max [um]", lambda s: s.estimation_max * 1e6),
              ("estimation deviation RMS [um]", lambda s: s.estimation_rms * 1e6)]


def format_scores(named: list, axes=None) -> str:
    """A plain-text table: one column per (name, Scores), one row per metric."""
    axes = axes or [f"axis{i}" for i in range(len(named[0][1].tracking_max))]
    rows = list(SCORE_ROWS)
    for i, axis in enumerate(axes):
        rows.append((f"tracking error max {axis} [um]", lambda s, i=i: s.tracking_max[i] * 1e6))
        rows.append((f"tracking error RMS {axis} [um]", lambda s, i=i: s.tracking_rms[i] * 1e6))
    for i, axis in enumerate(axes):
        rows.append((f"effort RMS {axis}", lambda s, i=i: s.effort_rms[i]))
    rows += [("travel time [s]", lambda s: s.travel_time), ("steps", lambda s: s.steps)]
    width = max(len(label) for label, _ in rows)
    columns = [max(12, len(name)) for name, _ in named]
    lines = ["  ".join([" " * width] + [name.rjust(w) for (name, _), w in zip(named, columns)])]
    for label, get in rows:
        cells = []
        for (_, scores), w in zip(named, columns):
            value = get(scores)
            cells.append(number(value, 4).rjust(w))
        lines.append("  ".join([label.ljust(width)] + cells))
    return "\n".join(lines)


def scores_lines(name: str, scores: Scores, axes, from_time: float = 0.0) -> list:
    """One run's scores as ``run`` and ``simulate`` print them: the table of :func:`format_scores`, after a
    heading where only the samples at t >= ``from_time`` count."""
    heading = [f"scores of the samples at t >= {from_time:g} s"] if from_time else []
    return heading + [format_scores([(name, scores)], axes)]


def recorded_lines(path, name: str, scores: Scores, run: RecordedRun, from_time: float = 0.0):
    """What the bag of a graph run tells once scored (``scores``, of the samples at t >= ``from_time``), line
    by line as each is ready: the scores (:func:`scores_lines`), the cutting moves' scores and the
    contour-tolerance verdict (:func:`cutting_lines`), and the realtime summary of its nodes
    (:func:`format_realtime`) where the run was realtime."""
    yield from scores_lines(name, scores, run.axes, from_time)
    yield from cutting_lines(curve_of(run), run.result, run.require_experiment())
    realtime = format_realtime(bag_reader.node_reports(path))
    if realtime:
        yield realtime


def json_scores(scores: Scores, axes) -> dict:
    """A run's scores for JSON: the Scores fields as they are (mce, tace, rms ... in metres), and the same
    per-axis values keyed by axis name, with the units spelled out."""
    out = scores.as_dict()
    out["axes"] = list(axes)
    for key in ("tracking_max", "tracking_rms", "effort_rms"):
        out[f"{key}_by_axis"] = dict(zip(axes, out[key]))
    out["units"] = {"mce": "m", "tace": "m", "rms": "m", "estimation_max": "m", "estimation_rms": "m",
                    "tracking_max": "m", "tracking_rms": "m", "effort_rms": "command units", "travel_time": "s",
                    "from_time": "s"}
    return out


def miss_rate(values: dict) -> float:
    """A node's deadline misses in percent of its ticks, a tick skipped (``on_overrun: skip``) counting as a
    miss; ``values`` is one node's end-of-run report (:func:`contouring_ros.records.bag_reader.node_reports`)."""
    skipped = int(values.get("skipped ticks", 0))
    return 100.0 * (int(values["deadline misses"]) + skipped) / max(1, int(values["ticks"]) + skipped)


def format_realtime(reports: dict) -> str:
    """The realtime summary of a run, one row per node, from :func:`contouring_ros.records.bag_reader.node_reports`
    ('' when the run was not realtime)."""
    rows = {name: values for name, values in reports.items() if "deadline misses" in values}
    if not rows:
        return ""
    width = max(len(name) for name in rows)
    header = ["node".ljust(width)] + [c.rjust(max(8, len(c))) for c in REALTIME_COLUMNS] + ["miss rate".rjust(9)]
    lines = ["realtime (per node; latency = tick to outputs sent; work = the node's own handling of a tick; "
             "a skipped tick counts as a miss):", "  ".join(header)]
    for name, values in sorted(rows.items()):
        cells = [str(values.get(c, "-")).rjust(max(8, len(c))) for c in REALTIME_COLUMNS]
        rate = miss_rate(values)
        lines.append("  ".join([name.ljust(width)] + cells + [f"{rate:8.2f}%"]))
    return "\n".join(lines)
