"""The claims report (reports/claims.md, ``contouring-ros paper``): per paper each claim's ratios with their
intervals and verdicts under both readings, the paper's own figure beside them, the sensitivity to the decisive
parameters, the regime maps and the CCC checks; a summary table of every claim first."""
from __future__ import annotations

import math
import sys
import time
from pathlib import Path

from ..records.outputs import write_atomically
from .claims import (DRAWS, MISMATCH, SCALES, ScenarioScores, ccc_helps_scores, evaluate, interval_text,
                     paper_ratio_text, ratio_text, sensitivity_text, um_text)
from .claims_file import METRICS, VERDICT_RULE, Pair, PaperClaims, claim_files, claim_verdict, load_claims
from .claims_maps import draw_map, map_ratios

__all__ = ["paper_section", "summary_table", "claims_report", "write_claims_report"]


def _files(pair: Pair | None) -> str:
    return "-" if pair is None else f"`{pair.proposed}` vs `{pair.baseline}`"


def paper_section(paper: PaperClaims, results: list, maps: dict, helps: list, directory, draws: int = DRAWS) -> str:
    """A paper's section of the report: per claim (``results``, ClaimResult) its table under both readings, the
    sensitivity table, the reason and the regime maps drawn (``maps``) or found in ``directory``; the CCC checks
    (``helps``: (CCCHelps, (with, without))) and the readings the scenario files choose."""
    lines = [f"## Paper {paper.paper}: {paper.title}", ""]
    for result in results:
        c = result.claim
        name = METRICS[c.metric] + (f" from t = {c.from_time:g} s" if c.from_time else ", whole run")
        lines += [f"### {c.id}: {c.claim}", "",
                  f"| | ratio ({name}): median [95% interval] of {draws} draws, realistic machine | proposed [um] | "
                  "baseline [um] | verdict | ideal machine: ratio, verdict | x0.7 / x1.4 | files |",
                  "|---|---:|---:|---:|---|---|---|---|",
                  f"| paper | {paper_ratio_text(c.paper_ratio)} | | | | | | {c.paper_figure} |"]
        for reading, label in (("faithful", "ours, faithful reading"), ("mechanism", "ours, where the mechanism acts")):
            lines.append(f"| {label} | {interval_text(result, reading)} | {um_text(result.value(reading, 0))} | "
                         f"{um_text(result.value(reading, 1))} | **{result.verdict(reading)}** | "
                         f"{ratio_text(result.ideal_ratio(reading))}, {result.ideal_verdict(reading)} | "
                         f"{sensitivity_text(result, reading)} | {_files(c.pair(reading))} |")
        lines += [""]
        if c.adds:
            lines += [f"Mechanism scenario adds (beyond the paper): {c.adds}", ""]
        if c.decisive:
            lines += ["Sensitivity (seed-0 ratio on the realistic machine; both files scaled alike):", "",
                      "| reading | unscaled | " + " | ".join(f"{d.label} x{f:g}" for d in c.decisive for f in SCALES) + " |",
                      "|---|---:|" + "---:|" * (len(c.decisive) * len(SCALES))]
            for reading in ("faithful", "mechanism"):
                if c.pair(reading) is None:
                    continue
                ratios = result.scaled_ratios(reading)
                nominal = result.nominal_ratio(reading)
                lines.append(f"| {reading} | {ratio_text(nominal)} ({claim_verdict(nominal, c.paper_ratio)}) | " + " | ".join(
                    f"{ratio_text(ratios.get((d.label, f)))} ({claim_verdict(ratios.get((d.label, f)), c.paper_ratio)})"
                    for d in c.decisive for f in SCALES) + " |")
            lines += [""]
        lines += [f"Why: {c.reason}", ""]
        for i, _ in enumerate(c.maps):
            png = c.map_path(i, directory)
            if png in maps or png.exists():
                lines.append(f"![regime map {c.id}](maps/{png.name})")
                lines.append("")
    if helps:
        lines += ["### The CCCs lower the contour error (ideal machine)", "",
                  "| scenario | without | metric | with CCC [um] | without [um] | ratio | stated factor |",
                  "|---|---|---|---:|---:|---:|---:|"]
        for entry, (with_ccc, without) in helps:
            ratio = with_ccc / without if without else math.nan
            lines.append(f"| `{entry.scenario}` | `{entry.without}` | {METRICS[entry.metric]}"
                         f"{f' from {entry.from_time:g} s' if entry.from_time else ''} | {with_ccc * 1e6:.3g} | "
                         f"{without * 1e6:.3g} | {ratio:.3g} | <= 1/{entry.factor:g} |")
        lines.append("")
    lines += ["### Readings the scenario files choose", ""] + [f"- {r}" for r in paper.readings] + [""]
    return "\n".join(lines)


def summary_table(rows: list) -> str:
    """The table of every claim (``rows``: (paper, ClaimResult)) at the head of the report."""
    lines = ["| paper | claim | metric | paper ratio | ours, faithful: median [95%] (ideal) | verdict, x0.7/x1.4 | "
             "ours, mechanism: median [95%] (ideal) | verdict, x0.7/x1.4 |",
             "|---|---|---|---:|---:|---|---:|---|"]
    for paper, result in rows:
        c = result.claim
        cells = []
        for reading in ("faithful", "mechanism"):
            cells.append(f"{interval_text(result, reading)} ({ratio_text(result.ideal_ratio(reading))}) | "
                         f"**{result.verdict(reading)}**, {result.robustness(reading)[0]}")
        lines.append(f"| {paper} | [{c.id}](#{c.id.replace('_', '-')}) {c.claim} | {METRICS[c.metric]}"
                     f"{f' (t >= {c.from_time:g} s)' if c.from_time else ''} | {paper_ratio_text(c.paper_ratio)} | "
                     + " | ".join(cells) + " |")
    return "\n".join(lines)


def claims_report(papers: list | None = None, directory="reports", maps: bool = True, workers: int | None = None,
                  progress=None, command: str = "all", draws: int = DRAWS, scheduler: str | None = None) -> str:
    """The claims report (Markdown) of the given papers (default: every claims file); with ``maps`` the regime
    maps are computed and drawn into ``directory``/maps first."""
    say = progress or (lambda message: None)
    started = time.monotonic()
    files = [load_claims(path) for path in claim_files()]
    files = [f for f in files if papers is None or f.paper in papers]
    scores = ScenarioScores(workers, scheduler=scheduler)
    sections, rows, drawn, map_seconds = [], [], {}, 0.0
    for paper in files:
        say(f"paper {paper.paper}: {len(paper.claims)} claims")
        begun = time.monotonic()
        results = evaluate(list(paper.claims), scores, draws=draws)
        say(f"  claims measured ({time.monotonic() - begun:.0f} s)")
        helps = [(entry, ccc_helps_scores(entry, scores)) for entry in paper.ccc_helps]
        if maps:
            for c in paper.claims:
                for i, spec in enumerate(c.maps):
                    begun = time.monotonic()
                    png = draw_map(c, spec, map_ratios(c, spec, workers, progress=sys.stderr.isatty(), scheduler=scheduler),
                                   c.map_path(i, directory))
                    map_seconds += time.monotonic() - begun
                    drawn[png] = True
                    say(f"  {png} ({time.monotonic() - begun:.0f} s)")
        rows += [(paper.paper, r) for r in results]
        sections.append(paper_section(paper, results, drawn, helps, directory, draws))
    head = ["# Claims: what each paper claims, and what we measure", "",
            f"Generated by `contouring-ros paper {command}` from `config/claims/paper<N>.yaml` (in-process simulation; the "
            "node graph reproduces it to the bit). Each claim is measured twice: under the faithful reading of the "
            "paper's own experiment, and in a mechanism scenario where the effect the paper relies on is present "
            "(chosen from the physics; its file header says why). Figures in micrometres; MCE = max, TACE = time "
            "average, RMS of the exact contour error (distance to the whole curve).", "",
            f"Machine: every ratio is measured on the realistic machine of `contouring_ros.studies.tuning` (0.1 um encoder, "
            "0.05 um RMS position noise, one sample of command delay, velocity from the encoder, an actuator limit "
            "of 2x the proposed file's ideal peak command where the file states none), made from the proposed file "
            f"and put under both files of the pair; the median and 2.5-97.5% interval are over {draws} paired "
            f"draws (draw j for both files: noise seeds, +-{100 * MISMATCH:g}% on every plant parameter, "
            "disturbance phase). The ideal machine's ratio (none of these, one run) is given beside it. The "
            "regime maps and the CCC checks are on the ideal machine (a realistic map with draws would take "
            "about ten times as long).", "", VERDICT_RULE, "",
            summary_table(rows), ""]
    took = time.monotonic() - started
    tail = [f"_{len(rows)} claims; {took:.0f} s on this machine"
            + (f", of which the regime maps {map_seconds:.0f} s" if maps else
               "; the regime maps were not recomputed (--no-maps: those drawn by the last run with maps)") + "._", ""]
    return "\n".join(head + sections + tail)


def write_claims_report(text: str, directory="reports", name: str = "claims.md") -> Path:
    """Write the report ``text`` to ``directory``/``name``, moved into place when whole."""
    return write_atomically(Path(directory) / name, lambda tmp: tmp.write_text(text))

