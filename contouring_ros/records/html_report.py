"""The HTML report of one recorded run or a comparison of runs: a self-contained page (figures embedded as PNG)
with the runs, their scores and ratios to a baseline run, how their experiments differ, the results per block of
tool path runs, every figure and each run's experiment YAML.
"""
from __future__ import annotations

import base64
import html
from pathlib import Path


from .blocks import block_cells, block_headings, block_results, cutting_scores
from .comparison import experiment_differences
from ..experiment.build import build_schedule
from ..errors import ContouringError
from .figures import draw_all, png_bytes
from .numbers import number, relative
from .outputs import write_atomically
from .scoring import SCORE_ROWS, motion_steps
from .traces import axis_union, traces_of

__all__ = ["CAPTIONS", "html_report"]

#: the caption of each figure in the report, by figure name
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


def _run_header(traces) -> str:
    return "<tr><th>metric</th>" + "".join(
        f'<th><span class="swatch" style="background:{t.colour}"></span>{html.escape(t.name)}</th>'
        for t in traces) + "</tr>"


def _html_scores(traces, scores) -> str:
    """The scores of every run as an HTML table."""
    rows = []
    for label, value in _score_rows(axis_union(traces)):
        cells = "".join(f'<td class="num">{number(value(s, t.axes) if s is not None else None, 4)}</td>'
                        for t, s in zip(traces, scores))
        rows.append(f"<tr><td>{html.escape(label)}</td>{cells}</tr>")
    return f'<h2>Scores</h2><div class="scroll"><table>{_run_header(traces)}{"".join(rows)}</table></div>'


def _ratio_cell(value, reference, is_baseline: bool) -> str:
    ratio = relative(value, reference)
    if ratio is None:
        return '<td class="num">-</td>'
    kind = "base" if is_baseline else "better" if ratio < 0.95 else "worse" if ratio > 1.05 else ""
    return f'<td class="num {kind}">{number(ratio)}</td>'


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
    return base64.b64encode(png_bytes(fig)).decode()


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
    traces = traces_of(runs)
    drawn = drawn if drawn is not None else draw_all(traces, magnification)
    title = "Contouring report: " + (" vs ".join(t.name for t in traces) if len(traces) <= 2 else
                                      f"{traces[0].name} and {len(traces) - 1} other runs")
    page = (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{_STYLE}</style></head><body><h1>{html.escape(title)}</h1>"
            f"{_html_runs(traces, runs)}{_html_differences(traces, runs)}"
            f"{_html_scores(traces, scores)}{_html_ratios(traces, scores, baseline)}"
            f"{_html_blocks(traces)}{_html_figures(drawn)}{_html_experiments(traces)}</body></html>")
    return write_atomically(path, lambda tmp: tmp.write_text(page))
