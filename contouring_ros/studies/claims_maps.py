"""A claim's regime maps: the claim's pair (its faithful or mechanism files) swept alike over one or two
variables on the ideal machine (grid keys as in :mod:`contouring_ros.studies.sweep`; a variable with several
keys sets them all), and drawn as proposed / baseline MCE and TACE with the contour where the paper's ratio is
reached (reports/maps/paper<N>_<claim id>.png)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..records.outputs import write_atomically
from .claims_file import METRICS, Claim, RegimeMap, scenario_experiment, scenario_value
from .sweep import experiments_for, score_experiments

__all__ = ["map_ratios", "draw_map"]


def _map_settings(spec: RegimeMap, side: str) -> list:
    """The settings of each map cell (row by row) for the ``side`` ('proposed' or 'baseline') file."""
    axes = [a for a in (spec.x, spec.y) if a is not None and a.only in (None, side)]
    out = []
    for y in (spec.y.values if spec.y else (None,)):
        for x in spec.x.values:
            value = {id(spec.x): x, id(spec.y): y}
            out.append({key: value[id(axis)] for axis in axes for key in axis.keys})
    return out


def map_ratios(claim: Claim, spec: RegimeMap, workers: int | None = None, progress: bool = False,
               scheduler: str | None = None) -> dict:
    """Proposed / baseline MCE and TACE (and the claim's metric) over the map's grid: metric -> (ny, nx) array
    (NaN where a run diverged), plus 'failures' (ny, nx) of reasons."""
    pair = claim.pair(spec.pair)
    if pair is None:
        raise ConfigError(f"claims {claim.paper}/{claim.id}: its map sweeps the {spec.pair} pair, which it lacks")
    experiments = []
    for name, side in ((pair.proposed, "proposed"), (pair.baseline, "baseline")):
        text = scenario_experiment(name).text
        experiments += [e for _, e in experiments_for(text, _map_settings(spec, side), where=f"{name} map")]
    results = score_experiments(experiments, workers, progress, from_time=claim.from_time,
                                desc=f"map {claim.paper}/{claim.id}", scheduler=scheduler)
    n = len(experiments) // 2
    shape = (len(spec.y.values) if spec.y else 1, len(spec.x.values))
    out = {"failures": np.array([p[2] or b[2] for p, b in zip(results[:n], results[n:])], dtype=object).reshape(shape)}
    for metric in dict.fromkeys(("tace", "mce", claim.metric)):
        ratios = [getattr(p[0], metric) / getattr(b[0], metric) if p[0] and b[0] and getattr(b[0], metric) > 0
                  else math.nan for p, b in zip(results[:n], results[n:])]
        out[metric] = np.array(ratios, dtype=float).reshape(shape)
    return out



def _nearest(values, value):
    try:
        return int(np.argmin([abs(float(v) - float(value)) for v in values]))
    except (TypeError, ValueError):
        return None


def draw_map(claim: Claim, spec: RegimeMap, ratios: dict, path) -> Path:
    """A PNG with one heatmap per metric (TACE, MCE): proposed / baseline, blue where the proposed method is
    better, the contour where the paper's ratio is reached, the scenario's own setting marked."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import TwoSlopeNorm

    metrics = list(dict.fromkeys([claim.metric, "tace", "mce"]))     # the claim's own metric first
    pair = claim.pair(spec.pair)
    fig, axes = plt.subplots(1, len(metrics), figsize=(6.3 * len(metrics), 5.6), constrained_layout=True)
    nx, ny = len(spec.x.values), len(spec.y.values) if spec.y else 1
    here = (_nearest(spec.x.values, scenario_value(pair.proposed, spec.x.keys[0])),
            _nearest(spec.y.values, scenario_value(pair.proposed, spec.y.keys[0])) if spec.y else 0)
    for ax, metric in zip(axes, metrics):
        grid = ratios[metric]
        logs = np.log10(np.where(grid > 0, grid, np.nan))
        span = max(0.05, float(np.nanmax(np.abs(logs))) if np.isfinite(logs).any() else 1.0)
        image = ax.imshow(logs, origin="lower", cmap="RdBu_r", norm=TwoSlopeNorm(0.0, -span, span), aspect="auto")
        for j in range(ny):
            for i in range(nx):
                value = grid[j, i]
                text = "diverged" if not math.isfinite(value) else f"{value:.2g}"
                shade = abs(logs[j, i]) / span if math.isfinite(logs[j, i]) else 0.0
                ax.text(i, j, text, ha="center", va="center", fontsize=8, color="white" if shade > 0.6 else "black")
        if metric == claim.metric and claim.paper_ratio and ny > 1 and nx > 1 and np.isfinite(logs).sum() >= 4:
            filled = np.where(np.isfinite(logs), logs, np.nanmax(logs) if np.isfinite(logs).any() else 0.0)
            target = math.log10(claim.paper_ratio)
            if filled.min() < target < filled.max():
                lines = ax.contour(np.arange(nx), np.arange(ny), filled, levels=[target], colors="black",
                                   linewidths=2.0, linestyles="--")
                ax.clabel(lines, fmt={target: f"paper {claim.paper_ratio:.2g}"}, fontsize=8)
        if here[0] is not None and here[1] is not None:
            from matplotlib.patches import Rectangle
            ax.add_patch(Rectangle((here[0] - 0.5, here[1] - 0.5), 1.0, 1.0, fill=False, edgecolor="gold",
                                   linewidth=3.0, label=f"the {spec.pair} scenario's setting"))
            ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.12), fontsize=8, framealpha=0.8)
        ax.set_xticks(range(nx), [f"{v:g}" if isinstance(v, (int, float)) else str(v) for v in spec.x.values])
        ax.set_xlabel(spec.x.label)
        if spec.y:
            ax.set_yticks(range(ny), [f"{v:g}" if isinstance(v, (int, float)) else str(v) for v in spec.y.values])
            ax.set_ylabel(spec.y.label)
        else:
            ax.set_yticks([])
        ax.set_title(f"{METRICS[metric]}: proposed / baseline")
        bar = fig.colorbar(image, ax=ax, shrink=0.85)
        ticks = [t for t in (0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0) if -span <= math.log10(t) <= span] \
            if span <= 1.3 else [10.0 ** e for e in range(-int(span), int(span) + 1, max(1, int(span) // 4))]
        bar.set_ticks([math.log10(t) for t in ticks], labels=[f"{t:g}" for t in ticks])
        bar.set_label("ratio (blue: proposed better)")
    fig.suptitle(f"Paper {claim.paper}, {claim.id}: {pair.proposed} vs {pair.baseline}\n"
                 + (f"paper's ratio {claim.paper_ratio:.2g} ({METRICS[claim.metric]}), dashed where reached"
                    if claim.paper_ratio else f"no paper figure ({METRICS[claim.metric]}: below 1 lowers)")
                 + "; ideal machine"
                 + (f"; scores from t = {claim.from_time:g} s" if claim.from_time else ""), fontsize=10)
    path = write_atomically(path, lambda tmp: fig.savefig(tmp, format="png", dpi=110))
    plt.close(fig)
    return path

