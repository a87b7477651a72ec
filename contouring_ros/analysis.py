"""Offline analysis of recorded runs: comparisons, estimator replay, figures and an HTML report.

Nothing here needs ROS: bags are read with :mod:`contouring_ros.bag`, figures drawn with matplotlib.
"""
from __future__ import annotations

import base64
import html
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from .bag import RecordedRun
from .config import ESTIMATORS, _typed, build_estimator, parse_experiment
from .core.geometry import ExactContourError
from .core.interpolation import Reference
from .errors import ConfigError
from .scoring import _ROWS, curve_of, format_scores

__all__ = ["compare_table", "parse_estimator_spec", "EstimatorReplay", "replay_estimators", "figures",
           "write_figures", "html_report"]


def compare_table(named: list, baseline: int = 0, axes=None) -> str:
    """Scores side by side, then each run's main metrics as a ratio to the baseline run."""
    table = format_scores(named, axes)
    base_name, base = named[baseline]
    lines = [table, "", f"ratio to {base_name}:"]
    width = max(len(label) for label, _ in _ROWS)
    columns = [max(12, len(name)) for name, _ in named]
    lines.append("  ".join([" " * width] + [name.rjust(w) for (name, _), w in zip(named, columns)]))
    for label, get in _ROWS:
        reference = get(base)
        cells = [(f"{get(scores) / reference:.3g}" if reference else "-").rjust(w)
                 for (_, scores), w in zip(named, columns)]
        lines.append("  ".join([label.split(" [")[0].ljust(width)] + cells))
    return "\n".join(lines)


def parse_estimator_spec(spec: str) -> dict:
    """'newton:k_prime=800,iterations=10' -> {'type': 'newton', 'k_prime': 800.0, 'iterations': 10}."""
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
    integer_keys = {k for k, p in ESTIMATORS.get(name, {}).items() if p.kind == "int"}
    return {k: (float(v) if isinstance(v, int) and k not in integer_keys else v) for k, v in section.items()}


@dataclass
class EstimatorReplay:
    """How one estimator tracks the exact contour error over a recorded run (lengths in metres)."""

    name: str
    estimate: np.ndarray          # |estimate| per step
    deviation_max: float
    deviation_rms: float


def replay_estimators(run: RecordedRun, specs: list, progress: bool = False) -> tuple[np.ndarray, list]:
    """Run each estimator of ``specs`` over the recorded reference and positions.

    Returns the exact contour error per step and, first for the recorded estimate and then for each spec,
    an :class:`EstimatorReplay`.
    """
    experiment = parse_experiment(run.experiment_text, "the bag's experiment")
    curve = curve_of(run)
    result = run.result
    exact = ExactContourError(curve)(result.position, near=result.theta).distance
    recorded = np.linalg.norm(result.estimate_vector, axis=1)
    replays = [_replay("recorded (" + experiment.estimator.get("type", "?") + ")", recorded, exact)]
    n = len(run.axes)
    for spec in specs:
        section = _typed("--estimator", spec["type"], "type", ESTIMATORS, spec)
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

def figures(runs: list, magnification: float | None = None) -> dict:
    """Matplotlib figures of one run or a comparison: name -> Figure.

    ``runs`` is a list of (label, RecordedRun). Figures: the reference path with each actual path, its
    contour error magnified; contour error against time; the estimate against the exact error; per-axis
    tracking error; per-axis actuator effort.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curve = curve_of(runs[0][1])
    solver = ExactContourError(curve)
    exacts = [solver(run.result.position, near=run.result.theta) for _, run in runs]
    out = {}

    fig, ax = plt.subplots(figsize=(7, 6))
    dense = curve.point(np.linspace(*curve.domain, 2000))
    ax.plot(dense[:, 0] * 1e3, dense[:, 1] * 1e3, "k-", lw=1, label="reference")
    span = float(np.ptp(dense[:, :2], axis=0).max())
    worst = max(float(foot.distance.max()) for foot in exacts) or 1.0
    gain = magnification or max(1.0, round(0.05 * span / worst, -int(np.floor(np.log10(0.05 * span / worst)))))
    for (label, run), foot in zip(runs, exacts):
        shown = run.result.position - (gain - 1.0) * foot.vector     # foot point - gain * error vector
        ax.plot(shown[:, 0] * 1e3, shown[:, 1] * 1e3, lw=1, label=f"{label} (error x{gain:g})")
    ax.set(xlabel="x [mm]", ylabel="y [mm]", title=f"Path, contour error magnified {gain:g}x", aspect="equal")
    ax.legend(fontsize=8)
    out["path"] = fig

    fig, ax = plt.subplots(figsize=(8, 4))
    for (label, run), foot in zip(runs, exacts):
        ax.plot(run.result.time, foot.distance * 1e6, lw=1, label=f"{label} exact")
    ax.set(xlabel="t [s]", ylabel="contour error [um]", title="Exact contour error")
    ax.legend(fontsize=8)
    out["contour_error"] = fig

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for (label, run), foot in zip(runs, exacts):
        estimate = np.linalg.norm(run.result.estimate_vector, axis=1)
        top.plot(run.result.time, foot.distance * 1e6, lw=1, label=f"{label} exact")
        top.plot(run.result.time, estimate * 1e6, "--", lw=1, label=f"{label} estimate")
        bottom.plot(run.result.time, np.abs(estimate - foot.distance) * 1e6, lw=1, label=label)
    top.set(ylabel="contour error [um]", title="Estimate against exact contour error")
    bottom.set(xlabel="t [s]", ylabel="|estimate - exact| [um]")
    top.legend(fontsize=8)
    bottom.legend(fontsize=8)
    out["estimate"] = fig

    axes = runs[0][1].axes
    fig, panels = plt.subplots(len(axes), 1, figsize=(8, 2.4 * len(axes)), sharex=True, squeeze=False)
    for i, axis in enumerate(axes):
        for label, run in runs:
            panels[i, 0].plot(run.result.time,
                              (run.result.reference_position[:, i] - run.result.position[:, i]) * 1e6,
                              lw=1, label=label)
        panels[i, 0].set(ylabel=f"{axis} tracking [um]")
    panels[0, 0].set_title("Tracking error R_i - P_i")
    panels[-1, 0].set_xlabel("t [s]")
    panels[0, 0].legend(fontsize=8)
    out["tracking"] = fig

    fig, panels = plt.subplots(len(axes), 1, figsize=(8, 2.4 * len(axes)), sharex=True, squeeze=False)
    for i, axis in enumerate(axes):
        for label, run in runs:
            panels[i, 0].plot(run.result.time, run.result.command[:, i], lw=1, label=f"{label} command")
            panels[i, 0].plot(run.result.time, run.result.correction[:, i], ":", lw=1, label=f"{label} CCC")
        panels[i, 0].set(ylabel=f"{axis} effort")
    panels[0, 0].set_title("Actuator command and cross-coupled correction [command units]")
    panels[-1, 0].set_xlabel("t [s]")
    panels[0, 0].legend(fontsize=8)
    out["effort"] = fig
    for fig in out.values():
        fig.tight_layout()
    return out


def write_figures(runs: list, directory, magnification: float | None = None) -> list:
    """Write :func:`figures` as PNG files into ``directory``; returns their paths."""
    import matplotlib.pyplot as plt
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, fig in figures(runs, magnification).items():
        path = directory / f"{name}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths


def html_report(runs: list, scores: list, path, magnification: float | None = None) -> Path:
    """A self-contained HTML page: the score table and every figure (embedded PNG) of one run or more."""
    import matplotlib.pyplot as plt
    images = []
    for name, fig in figures(runs, magnification).items():
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png", dpi=100)
        plt.close(fig)
        images.append((name, base64.b64encode(buffer.getvalue()).decode()))
    table = format_scores([(label, s) for (label, _), s in zip(runs, scores)], runs[0][1].axes)
    experiments = "".join(f"<details><summary>experiment of {html.escape(label)}</summary><pre>"
                          f"{html.escape(run.experiment_text)}</pre></details>" for label, run in runs)
    body = "".join(f'<h2>{name.replace("_", " ")}</h2><img alt="{name}" src="data:image/png;base64,{data}">'
                   for name, data in images)
    warnings = "".join(f"<p><b>warning:</b> {html.escape(w)}</p>" for _, run in runs for w in run.warnings)
    page = (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>contouring_ros report</title>"
            f"<style>body{{font-family:sans-serif;max-width:60em;margin:auto}}img{{max-width:100%}}</style>"
            f"</head><body><h1>contouring_ros run report</h1>{warnings}<pre>{html.escape(table)}</pre>"
            f"{experiments}{body}</body></html>")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(page)
    return path
