"""The benchmark's figures, drawn from its rows: the heatmap of every combination's TACE relative to its
scenario's proposed method, and per paper the Pareto fronts of error against noise sensitivity that each
method's search evaluated (reports/benchmark_heatmap.png, benchmark_pareto_paper<N>.png)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..experiment.catalogue import CONTROLLERS, ESTIMATORS
from ..records.outputs import write_atomically
from .benchmark import Combination, Family, lower_or_higher
from .summaries import pareto_front

__all__ = ["draw_heatmap", "draw_pareto"]


def _column(combination: Combination) -> tuple:
    """A heatmap column: (controller, estimator); the uncoupled controller reads no estimate: one column."""
    return (combination.controller, "-" if combination.controller == "none" else combination.estimator)


def _column_order(rows: list) -> list:
    controllers, estimators = CONTROLLERS.names(), ESTIMATORS.names()
    pairs = {_column(r.combination) for r in rows if r.combination}
    return sorted(pairs, key=lambda p: (controllers.index(p[0]) if p[0] in controllers else 99,
                                        estimators.index(p[1]) if p[1] in estimators else 99))


def draw_heatmap(rows: list, path) -> Path:
    """Scenario (and servo) x estimator + controller: colour = log10 of the median steady-state TACE over
    the proposed combination's (both tuned alike, paired draws); '~' marks a ratio whose 95% interval
    crosses 1; grey: cannot be paired; x: no admissible gain."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import TwoSlopeNorm
    columns = _column_order(rows)
    keys = []
    for r in rows:
        if r.combination and (r.family.name, r.combination.servo) not in keys:
            keys.append((r.family.name, r.combination.servo))
    cells = {(r.family.name, r.combination.servo, *_column(r.combination)): r for r in rows if r.combination}
    values = np.full((len(keys), len(columns)), np.nan)
    for i, (family, servo) in enumerate(keys):
        for j, (controller, estimator) in enumerate(columns):
            row = cells.get((family, servo, controller, estimator))
            ratio = row.ratio("tace")[0] if row else math.nan
            if math.isfinite(ratio) and ratio > 0:
                values[i, j] = math.log10(ratio)
    fig, ax = plt.subplots(figsize=(2.2 + 0.6 * len(columns), 1.6 + 0.34 * len(keys)))
    ax.set_facecolor("#dddddd")
    image = ax.imshow(np.clip(values, -2, 2), cmap="RdBu_r", norm=TwoSlopeNorm(0.0, -2.0, 2.0), aspect="auto")
    for i, (family, servo) in enumerate(keys):
        for j, (controller, estimator) in enumerate(columns):
            row = cells.get((family, servo, controller, estimator))
            if row is None:
                continue
            if not row.ok:
                ax.text(j, i, "x", ha="center", va="center", fontsize=8, color="black")
            else:
                median, low, high = row.ratio("tace")
                if math.isfinite(median):
                    mark = "" if row.is_proposed or lower_or_higher(low, high) != "undecided" else "~"
                    ax.text(j, i, f"{mark}{median:.2g}", ha="center", va="center", fontsize=6,
                            color="white" if abs(values[i, j]) > 1.2 else "black")
            if row.is_proposed:
                ax.add_patch(plt.Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, lw=1.8, ec="black"))
    ax.set_xticks(range(len(columns)))
    ax.set_xticklabels([f"{c} (uncoupled)" if e == "-" else f"{c} + {e}" for c, e in columns], rotation=60,
                       ha="right", fontsize=8)
    for j in range(1, len(columns)):
        if columns[j][0] != columns[j - 1][0]:
            ax.axvline(j - 0.5, color="black", lw=0.8)
    ax.set_yticks(range(len(keys)))
    ax.set_yticklabels([f"{f}  [{s}]" for f, s in keys], fontsize=8)
    for i in range(1, len(keys)):
        if keys[i][0][:8] != keys[i - 1][0][:8]:
            ax.axhline(i - 0.5, color="black", lw=1.2)
    bar = fig.colorbar(image, ax=ax, fraction=0.025, pad=0.01)
    bar.set_label("log10 median (TACE / proposed method's TACE), paired draws")
    ax.set_title("Contouring benchmark on the realistic machine, every gain tuned under equal constraints: TACE "
                 "relative to the proposed method (boxed).\nBlue: lower; ~: the 95% interval crosses 1 "
                 "(undecided); grey: cannot be paired; x: no admissible gain", fontsize=9)
    path = write_atomically(path, lambda tmp: fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight"))
    plt.close(fig)
    return path


def _pareto_rows(rows: list, family: Family, top: int = 4) -> list:
    mine = [r for r in rows if r.family is family and r.ok]
    ranked = sorted(mine, key=lambda r: r.figure("tace")[0])
    shown = [r for r in ranked if not r.is_proposed][:top]
    proposed = next((r for r in mine if r.is_proposed), None)
    return ([proposed] if proposed else []) + shown


def draw_pareto(rows: list, families: list, paper: str, path) -> Path:
    """One panel per scenario of ``paper``: steady-state TACE against noise sensitivity (RMS of the
    command's sample-to-sample change, relative to the proposed method with the paper's gains) of every
    point each method's search evaluated that stayed stable, with each method's Pareto front, the noise
    bound and the tuned points."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    mine = [f for f in families if f.paper == paper]
    cols = min(3, len(mine))
    lines = math.ceil(len(mine) / cols)
    fig, axes = plt.subplots(lines, cols, figsize=(max(5.2 * cols, 9.0), 4.2 * lines), squeeze=False)
    for ax, family in zip(axes.flat, mine):
        shown = _pareto_rows(rows, family)
        bound = shown[0].bound if shown else None
        scale = bound.published.noise if bound and bound.published.ok and bound.published.noise > 0 else 1.0
        stars = [r.tuned.nominal.tace * 1e6 for r in shown]
        top = 30.0 * max(stars) if stars else math.inf          # the region of interest: near the tuned points
        bound_x = bound.noise_limit / scale if bound and math.isfinite(bound.noise_limit) else 10.0
        for k, row in enumerate(shown):
            colour = "black" if row.is_proposed else f"C{k}"
            points = [(e.outcome.noise / scale, e.outcome.tace * 1e6) for e in row.tuned.evaluations
                      if e.outcome.ok and e.outcome.tace * 1e6 <= top and e.outcome.noise / scale <= 5 * bound_x]
            if points:
                xs, ys = zip(*points)
                ax.scatter(xs, ys, s=6, color=colour, alpha=0.25)
                front = pareto_front(points)
                ax.plot([p[0] for p in front], [p[1] for p in front], "-", color=colour, lw=1.2,
                        label=f"{row.label}{' (proposed)' if row.is_proposed else ''}")
            n = row.tuned.nominal
            ax.plot([n.noise / scale], [n.tace * 1e6], "*", color=colour, ms=11, mec="white")
        if bound and math.isfinite(bound.noise_limit):
            ax.axvline(bound.noise_limit / scale, color="grey", ls="--", lw=1)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlim(right=5 * bound_x)
        ax.set_title(family.name, fontsize=9)
        ax.set_xlabel("noise sensitivity / proposed method's with the paper's gains")
        ax.set_ylabel("steady-state TACE [um]")
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=6, loc="upper right")
        ax.grid(True, which="both", alpha=0.2)
    for ax in list(axes.flat)[len(mine):]:
        ax.set_visible(False)
    fig.suptitle(f"Paper {paper}: TACE against noise sensitivity of every stable point each search evaluated\n"
                 "lines: Pareto fronts; stars: tuned; dashed: the noise bound; points beyond 30x the worst tuned "
                 "TACE or 5x the noise bound left out", fontsize=9)
    fig.tight_layout()
    path = write_atomically(path, lambda tmp: fig.savefig(tmp, format="png", dpi=100))
    plt.close(fig)
    return path
