"""The benchmark's report, written from its rows: reports/benchmark.md (the protocol, per paper the best
combination against the proposed method with intervals and the findings, the literature's reference methods,
per scenario every combination, the pairings that cannot be made) and benchmark.csv (one row per scenario and
combination), with the figures of :mod:`.benchmark_figures`; and a run of the benchmark written out
(:func:`main_benchmark`)."""
from __future__ import annotations

import csv
import json
import math
import os
import time
from pathlib import Path

import numpy as np
import yaml

from ..experiment.scenarios import CONFIG_DIR
from ..records.numbers import csv_cell, median_interval, number
from ..records.outputs import write_atomically
from .benchmark import NOT_CONVERGED, Combination, Family, Part, Row, run_benchmark, scenario_families, select_families
from .benchmark_figures import draw_heatmap, draw_pareto
from .benchmark_parts import merged_rows, save_part
from .checkpoints import Checkpoints
from .machine import REALISTIC, SATURATION_MARGIN
from .tuning import Protocol, Tuned

__all__ = ["GOAL", "REFERENCE_SERVOS", "REFERENCE_CONTROLLERS", "write_csv", "best_other_rank", "paper_best",
           "reference_ranks", "convergence_text", "benchmark_report", "read_notes", "write_outputs", "main_benchmark"]

GOAL = 0.5              # a combination beats the proposed method 2x when both ratios' intervals are below this


# ---------------------------------------------------------------------------------------------- the table


def write_csv(rows: list, path) -> Path:
    """One row per scenario x combination: tuned gains, what the search used, the nominal figures, and the
    median and 95% interval over the draws (lengths in micrometres; ratios to the tuned proposed method,
    draw by draw)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    head = ["paper", "scenario", "proposed_file", "estimator", "controller", "servo", "proposed", "status",
            "from_s", "gains", "file_gains", "tuned_point", "at_bound", "evaluations", "searches", "searches_agreed",
            "searches_spread", "converged", "robustness_runs", "robust_worst",
            "tace_um", "mce_um", "noise", "noise_ratio", "saturated_share", "effort_rms",
            "tace_median_um", "tace_lo_um", "tace_hi_um", "mce_median_um", "mce_lo_um", "mce_hi_um",
            "tace_ratio", "tace_ratio_lo", "tace_ratio_hi", "mce_ratio", "mce_ratio_lo", "mce_ratio_hi",
            "tace_verdict", "ideal_tace_um", "ideal_mce_um", "ms", "gain_margin", "phase_margin_deg"]
    def write(tmp):
        with open(tmp, "w", newline="") as stream:
            writer = csv.writer(stream)
            writer.writerow(head)
            for row in rows:
                c = row.combination or row.excluded
                t = row.tuned
                n = t.nominal if row.ok else None
                tace, mce = row.figure("tace"), row.figure("mce")
                tr, mr = row.ratio("tace"), row.ratio("mce")
                writer.writerow([
                    row.family.paper, row.family.name, row.family.proposed, c.estimator, c.controller, c.servo,
                    "yes" if row.is_proposed else "", row.status, f"{row.family.from_time:g}",
                    json.dumps(t.gains) if row.ok else "", json.dumps(t.file_gains) if t else "",
                    json.dumps(t.point) if row.ok else "",
                    "; ".join(t.at_bound) if t else "", len(t.evaluations) if t else "",
                    *((a.searches, a.agreed, csv_cell(a.spread), "yes" if a.converged else "no")
                      if (a := t and t.agreement) else ("",) * 4),
                    t.robustness_runs if t else "", csv_cell(t.robust_worst) if t else "",
                    csv_cell(n.tace if n else None, 1e6), csv_cell(n.mce if n else None, 1e6), csv_cell(n.noise if n else None),
                    csv_cell(row.noise_ratio), csv_cell(n.saturated if n else None), csv_cell(n.effort if n else None),
                    *(csv_cell(v, 1e6) for v in tace), *(csv_cell(v, 1e6) for v in mce),
                    *(csv_cell(v) for v in tr), *(csv_cell(v) for v in mr),
                    "" if row.is_proposed else row.tace_verdict(),
                    csv_cell(t.ideal.tace if t and t.ideal else None, 1e6), csv_cell(t.ideal.mce if t and t.ideal else None, 1e6),
                    *((csv_cell(m.ms), csv_cell(m.gain_margin), csv_cell(m.phase_margin_deg)) if (m := t and t.margins) else ("",) * 3)])
    write_atomically(path, write)
    return path


# ---------------------------------------------------------------------------------------------- the report


def best_other_rank(tace_ratio: float, mce_ratio: float) -> tuple:
    """How the report ranks another combination against the proposed one, lowest first: the larger of its
    median MCE and TACE ratios to the tuned proposed combination, then its TACE ratio (used by
    :func:`paper_best` and by ``tools/compare_benchmarks.py`` on a CSV's rows)."""
    return max(mce_ratio, tace_ratio), tace_ratio


def paper_best(rows: list, family: Family) -> tuple:
    """(the proposed row, the best other row): the row with the lowest larger median ratio of MCE and TACE
    to the tuned proposed combination; every row met the same noise, saturation and robustness
    constraints, and whose searches agreed (:attr:`Row.converged`)."""
    mine = [r for r in rows if r.family is family and r.ok]
    proposed = next((r for r in mine if r.is_proposed), None)
    if proposed is None:
        return None, None
    others = [r for r in mine if not r.is_proposed and r.status == "ok" and r.converged
              and math.isfinite(r.ratio("tace")[0]) and math.isfinite(r.ratio("mce")[0])]
    best = min(others, key=lambda r: best_other_rank(r.ratio("tace")[0], r.ratio("mce")[0]), default=None)
    return proposed, best


def _goal(best: Row) -> str:
    tace, mce = best.ratio("tace"), best.ratio("mce")
    if tace[2] <= GOAL and mce[2] <= GOAL:
        return "**yes**"
    if tace[1] > GOAL or mce[1] > GOAL:
        return "no"
    return "undecided"


def _best_table(rows: list, families: list) -> list:
    lines = ["| scenario | proposed (tuned) | proposed TACE / MCE [um] | best other | TACE / MCE [um] | "
             "TACE ratio [95%] | MCE ratio [95%] | TACE verdict | 2x in both |",
             "|---|---|---|---|---|---|---|---|---|"]
    for family in families:
        proposed, best = paper_best(rows, family)
        if proposed is None:
            lines.append(f"| {family.name} | `{family.proposed}`: no admissible result | | | | | | | |")
            continue
        here = (f"| {family.name} | {proposed.label} | {number(proposed.figure('tace')[0], scale=1e6)} / "
                f"{number(proposed.figure('mce')[0], scale=1e6)} ")
        if best is None:
            lines.append(here + "| no other combination | | | | | |")
            continue
        tr = best.ratio("tace")
        lines.append(here + f"| {best.label} | {number(best.figure('tace')[0], scale=1e6)} / {number(best.figure('mce')[0], scale=1e6)} "
                     f"| {median_interval(*tr)} | {median_interval(*best.ratio('mce'))} | {best.tace_verdict()} | "
                     f"{_goal(best) if best.tace_verdict() != NOT_CONVERGED else NOT_CONVERGED} |")
    return lines


#: the literature's reference methods the report ranks apart: servo laws and controllers by name
REFERENCE_SERVOS = ("zpetc",)
REFERENCE_CONTROLLERS = ("ilc", "mpcc")


def _is_reference(combination: Combination) -> bool:
    return combination.controller in REFERENCE_CONTROLLERS or combination.servo.split(" ")[0] in REFERENCE_SERVOS


def reference_ranks(rows: list, family: Family) -> list:
    """(row, rank or None, admissible count) of each reference-method row of ``family``: its place by median
    TACE among the rows that met every constraint (status ok); None where it did not."""
    mine = [r for r in rows if r.family is family and r.combination]
    admissible = sorted((r for r in mine if r.ok and r.status == "ok"), key=lambda r: r.figure("tace")[0])
    return [(r, admissible.index(r) + 1 if r in admissible else None, len(admissible))
            for r in mine if _is_reference(r.combination)]


def _reference_table(rows: list, families: list) -> list:
    lines = ["| scenario | combination | rank | TACE [um] median [95%] | MCE [um] median [95%] | TACE ratio to "
             "proposed [95%] | MCE ratio [95%] | verdict | status |", "|---|---|---|---|---|---|---|---|---|"]
    for family in families:
        for r, rank, count in reference_ranks(rows, family):
            tr = r.ratio("tace")
            lines.append(f"| {family.name} | {r.label} | {f'{rank} of {count}' if rank else '-'} | "
                         f"{median_interval(*r.figure('tace'), scale=1e6)} | "
                         f"{median_interval(*r.figure('mce'), scale=1e6)} | {median_interval(*tr)} | "
                         f"{median_interval(*r.ratio('mce'))} | {r.tace_verdict() or '-'} | {r.status} |")
    return lines


def _gain_text(row: Row) -> str:
    if not row.ok or not row.gains:
        return "-"
    point = getattr(row.tuned, "point", {}) or {}
    text = getattr(row.tuned, "point_text", "") or ", ".join(    # a part saved before the space wrote it
        f"{k} {'off' if v == 0 else number(v)}" for k, v in point.items())
    raw = ", ".join(f"{k} {number(v)}" for k, v in row.gains.items())
    text = f"{text} ({raw})" if text else raw
    return text + (f"; {'; '.join(row.tuned.at_bound)}" if row.tuned.at_bound else "")


def _searches_cell(row: Row) -> str:
    a = getattr(row.tuned, "agreement", None) if row.tuned else None
    if a is None:
        return "-"
    return f"{a.agreed}/{a.searches}" + ("" if a.converged else " (not converged)")


def _margin_text(m) -> str:
    if m is None:
        return "-"
    unstable = "" if m.stable else ", unstable"
    return f"{m.ms:.2f} ({number(m.gain_margin, 2)}, {m.phase_margin_deg:.0f} deg{unstable})"


def _family_table(rows: list, family: Family) -> list:
    mine = [r for r in rows if r.family is family and r.combination]
    ranked = sorted(mine, key=lambda r: (not r.ok, r.figure("tace")[0] if r.ok else 0.0))
    ref = mine[0].bound if mine else None
    published = ref.published if ref else None
    head = [f"Steady state from t = {family.from_time:g} s; proposed file `{family.proposed}`, {len(mine)} "
            "combinations. The proposed method with the paper's gains on this machine: "
            + (f"TACE {number(published.tace, scale=1e6)} um, MCE {number(published.mce, scale=1e6)} um (ideal machine: "
               f"{number(ref.ideal_published.tace, scale=1e6)} / {number(ref.ideal_published.mce, scale=1e6)} um)."
               if published and published.ok else f"{published.failure if published else 'no run'}."), "",
            "| combination | tuned point (raw gains) | evals | searches agreed | TACE [um] median [95%] | MCE [um] "
            "median [95%] | TACE ratio [95%] | verdict | noise / paper's | saturated | worst at +-20% | Ms (GM, PM) | "
            "ideal machine TACE / MCE [um] |",
            "|---|---|---:|---|---|---|---|---|---:|---:|---:|---|---|"]
    for r in ranked:
        name = f"**{r.label}** (proposed)" if r.is_proposed else r.label
        t = r.tuned
        if not r.ok:
            head.append(f"| {name} | - | {len(t.evaluations) if t else 0} | {_searches_cell(r)} | {r.status} "
                        "| | | | | | | | |")
            continue
        tr = r.ratio("tace")
        status = "" if r.status == "ok" else " (not robust)"
        ideal = t.ideal
        head.append(f"| {name} | {_gain_text(r)} | {len(t.evaluations)} | {_searches_cell(r)} | "
                    f"{median_interval(*r.figure('tace'), scale=1e6)} | {median_interval(*r.figure('mce'), scale=1e6)} | "
                    f"{'1' if r.is_proposed else median_interval(*tr)} | "
                    f"{'' if r.is_proposed else r.tace_verdict()}{status} | {number(r.noise_ratio)} | "
                    f"{number(100 * t.nominal.saturated, 2)}% | {number(t.robust_worst)}x | {_margin_text(t.margins)} | "
                    f"{number(ideal.tace, scale=1e6) if ideal and ideal.ok else 'diverged'} / "
                    f"{number(ideal.mce, scale=1e6) if ideal and ideal.ok else '-'} |")
    return head


def _excluded_table(rows: list) -> list:
    groups = {}
    for r in rows:
        if r.excluded is None:
            continue
        reason = r.excluded.reason
        key = (r.excluded.controller, reason)
        entry = groups.setdefault(key, [set(), set()])
        entry[0].add(r.excluded.estimator if r.excluded.servo == "any" else f"{r.excluded.estimator} / {r.excluded.servo}")
        entry[1].add(r.family.name)
    lines = ["| controller | estimator (/ servo) | scenarios | why it cannot be paired |", "|---|---|---|---|"]
    for (controller, reason), (pairs, families) in sorted(groups.items()):
        fams = sorted(families)
        shown = ", ".join(fams) if len(fams) <= 4 else f"{len(fams)} scenarios ({', '.join(fams[:3])} ...)"
        lines.append(f"| {controller} | {', '.join(sorted(pairs))} | {shown} | {reason.replace('|', '/')} |")
    return lines


def convergence_text(tuned: list) -> str:
    """How many tuned rows converged (their searches agreed, :func:`contouring_ros.studies.search.agreement`), how many
    searches they took, and the rows that did not, each with its searches' spread."""
    if not tuned:
        return ""
    agreements = [r.tuned.agreement for r in tuned if getattr(r.tuned, "agreement", None) is not None]
    if not agreements:
        return ""
    converged = [r for r in tuned if r.converged]
    searches = [a.searches for a in agreements]
    inadmissible = [r for r in converged if getattr(r.tuned, "status", "ok") != "ok"]
    text = (f" **Convergence**: {len(converged)} of {len(tuned)} tuned rows converged "
            f"({100 * len(converged) / len(tuned):.0f}%)"
            + (f", {len(inadmissible)} of them rows without an admissible point whose searches agree on the "
               f"optimum of the objective, penalties included (the conflict of constraints their status names)"
               if inadmissible else "")
            + f"; searches per row: median {float(np.median(searches)):g}, at most {max(searches)}.")
    left = [r for r in tuned if not r.converged]
    if left:
        text += " Not converged (no verdict rests on them; each search's nominal TACE in um): " + "; ".join(
            f"{r.family.name} {r.label} ({r.tuned.agreement.agreed} of {r.tuned.agreement.searches} agree, "
            f"spread {number(r.tuned.agreement.spread)}x{_search_taces(r.tuned)})" for r in left) + "."
    return text


def _search_taces(tuned) -> str:
    """': ' and a row's searches' nominal TACEs in um, lowest first (nothing where it kept none)."""
    values = sorted(v * 1e6 for v in getattr(tuned, "search_tace", ()) or () if v == v)
    return (": " + ", ".join(f"{v:.3g}" for v in values)) if values else ""


def benchmark_report(rows: list, families: list, protocol: Protocol, where: str,
                     heatmap: str = "benchmark_heatmap.png", notes: dict | None = None,
                     pareto: dict | None = None) -> str:
    """reports/benchmark.md: header, the protocol, per paper the best combination against the proposed
    method with intervals and the findings, per scenario every combination, the pairs that cannot be made."""
    notes, pareto = notes or {}, pareto or {}
    left_out = bool(notes) and protocol != Protocol()
    if left_out:            # the findings describe the default run's figures, not this protocol's
        notes = {}
    compatible = [r for r in rows if r.combination]
    lines = _header_lines(rows, families, where) + _protocol_lines(compatible, protocol) + (
        ["The findings written for the default protocol's run (config/benchmark/notes.yaml) are left out: "
         "this run's protocol differs, and its figures may not say the same.", ""] if left_out else []) + [
        f"![TACE relative to the proposed method]({heatmap})", "",
        "## Per paper: the best combination against the proposed method", ""]
    for paper in sorted({f.paper for f in families}):
        mine = [f for f in families if f.paper == paper]
        lines += [f"### Paper {paper}", ""] + _best_table(rows, mine) + [""]
        if paper in notes:
            lines += [notes[paper].strip(), ""]
        if paper in pareto:
            lines += [f"![Paper {paper}: TACE against noise sensitivity]({pareto[paper]})", ""]
    lines += ["## The literature's reference methods", "",
              "ZPETC feedforward (a servo law), cross-coupled ILC and MPCC (contour controllers) "
              "(docs/REFERENCES.md), each tuned and scored as every other combination. Rank: its place by "
              "median TACE among the scenario's combinations that met every constraint (1 = lowest).", ""] \
        + _reference_table(rows, families) + [""]
    if "reference" in notes:
        lines += [notes["reference"].strip(), ""]
    lines += _time_table(compatible)
    lines += ["## Per scenario", ""]
    for family in families:
        lines += [f"### {family.name}", ""] + _family_table(rows, family) + [""]
    lines += ["## Pairings that cannot be made", ""] + _excluded_table(rows) + [""]
    return "\n".join(lines)


def _header_lines(rows: list, families: list, where: str) -> list:
    """The report's title and what it holds: the scenarios, combinations and runs, how figures are given."""
    compatible = [r for r in rows if r.combination]
    runs = sum(len(r.tuned.evaluations) + r.tuned.robustness_runs + r.tuned.selection_runs + len(r.tuned.draws) + 1
               for r in compatible if r.tuned)
    return [
        "# Contouring benchmark: every estimator and controller on every scenario, each gain tuned under equal "
        "constraints on a realistic machine", "",
        f"{where}; in-process simulation): {len(families)} scenarios "
        f"of {len({f.paper for f in families})} papers, {len(compatible)} combinations ({runs} runs), "
        f"{len(rows) - len(compatible)} pairings that cannot be made. Every figure in micrometres is the exact "
        "contour error (distance to the whole curve) in the scenario's steady state; ratios are to the scenario's "
        "proposed method tuned the same way, draw by draw. All rows: [benchmark.csv](benchmark.csv).", ""]


def _protocol_lines(compatible: list, protocol: Protocol) -> list:
    """The report's protocol: the machine, the tuning, the constraints, the intervals, and where the searches
    of the ``compatible`` rows (those with a combination) ended."""
    tuned = [r for r in compatible if r.ok and r.tuned.space]
    at_bound = [r for r in tuned if r.tuned.at_bound]
    upper = [r for r in tuned if any("upper" in b for b in r.tuned.at_bound)]
    not_robust = [r for r in compatible if r.tuned and r.status.startswith("not robust")]
    none = [r for r in compatible if not r.ok]
    machine = ", ".join(f"{k} {v}" for k, v in REALISTIC.items())
    return [
        "## Protocol", "",
        f"- **Machine** (every run unless marked ideal): the scenario's plants with {machine} (Altintas, "
        "Manufacturing Automation, 2012, ch. 5-6: 0.1-1 um encoders, 1 kHz loops, velocity from the encoder), "
        "and an actuator limit: the paper's where its file states one, else "
        f"{SATURATION_MARGIN:g} x the largest command the proposed method needs with the paper's gains. A key a "
        "scenario file sets itself is kept. The last column of each scenario table runs the same tuned gains "
        "on the ideal machine (the file as it is: no noise, quantisation, delay or added limit).",
        f"- **Tuning, the same for every method**: {protocol.describe()}. The spaces "
        "(contouring_ros/core/tuning_space.py): PID contour controllers (variable_gain, unit_vector) whose "
        "coupled loops are linear (PID and cascade servos): at a chosen Ms, by their PI corner frequency "
        "(f_c, 0.01 Hz to an eighth of the sample rate, or off), derivative time (t_d, 10 us to 0.1 s, or off) "
        "and the Ms their loops reach (1.2 to the bound), the gain scale solved for that Ms, the top of the "
        "lowest range of scales within it or of the highest stable one (gain_range 0 or 1); the ZPETC's PID "
        "likewise, at a chosen Ms of each axis' own loop (each axis' largest stable gain scale at that Ms; a "
        "contour controller beside it then in crossover frequencies, its coupled loop held to the bound); the "
        "other PID contour controllers: the proportional and integral terms' crossover frequencies "
        "through the axes' plant (f_p, f_i, each 0.1 Hz to an eighth of the sample rate, or off) and the "
        "derivative's ratio to the proportional term at f_p (r_d); task_frame_pd: its bandwidths and damping ratio; tvt: its bandwidth; "
        "adaptive_tnb: its tracking gain alpha as 2 pi f_alpha (0.1 Hz to 4x the sample rate) and its coupling "
        "and adaptation gains as ratios to the paper's; "
        "ILC: its learning gains as ratios to the file's, its lead and its Q-filter cutoff; MPCC: its horizon "
        "and its weight ratios. The file's gains are the first search's first evaluation. Estimators and the "
        "papers' servos keep the scenario's sections (the servos are the drives' own loops, shared by every "
        "contour method).",
        "- **Constraints**: noise sensitivity = RMS of the command's sample-to-sample change in the steady state; "
        "saturation = share of steady-state steps with a command at its limit; robustness = stable with TACE "
        "within the stated factor of nominal, or no worse than the proposed method's worst with the paper's "
        "gains, at each plant parameter (gain, time constant, mass, damping) "
        f"+-{100 * protocol.perturbation:g}% on every axis, run for every point of every search in the same "
        "batch as its nominal run (a point that fails is inadmissible, its objective paying for it). "
        "A row marked *not robust* had no robust point: of its points that met every other constraint, the one "
        "with the lowest worst case is shown, and "
        "it cannot be the best of its scenario.",
        f"- **Intervals**: each tuned method runs {protocol.draws} draws (noise seed, model mismatch within "
        f"+-{100 * protocol.mismatch:g}% of every plant parameter), the same draws for every method of a "
        "scenario; figures are the median [2.5%, 97.5%] over the draws, ratios are taken draw by draw. A "
        "verdict is *lower* or *higher* only where the whole interval is on one side of 1, else *undecided*; "
        f"the 2x goal needs both ratios' intervals at or below {GOAL:g}.",
        f"- **Where the search ended**: {len(at_bound)} of {len(tuned)} tuned combinations have a coordinate at "
        f"an end of its range ({len(upper)} at an upper bound, where a larger value might do better; the others "
        f"with a term switched off or at a lower bound). {len(not_robust)} not robust; {len(none)} without an admissible "
        "point." + convergence_text(tuned), ""]


def _time_table(rows: list) -> list:
    """Where the CPU time went: per contour controller, the rows, their CPU time in all and the longest
    row's (rows tuned before the time was kept are left out)."""
    timed = [r for r in rows if r.tuned and math.isfinite(r.tuned.cpu)]     # an older part's Tuned: nan
    if not timed:
        return []
    total = sum(r.tuned.cpu for r in timed)
    lines = ["## Where the time went", "",
             f"CPU time of each combination's tuning, robustness checks and draws (one core each), "
             f"{len(timed)} of {len(rows)} combinations timed: {total / 60:.1f} min in all.", "",
             "| controller | combinations | CPU [min] | share | longest [min] (scenario) |", "|---|---:|---:|---:|---|"]
    by = {}
    for row in timed:
        by.setdefault(row.combination.controller, []).append(row)
    for controller, mine in sorted(by.items(), key=lambda kv: -sum(r.tuned.cpu for r in kv[1])):
        cpu = sum(r.tuned.cpu for r in mine)
        longest = max(mine, key=lambda r: r.tuned.cpu)
        lines.append(f"| {controller} | {len(mine)} | {cpu / 60:.1f} | {100 * cpu / total:.0f}% | "
                     f"{longest.tuned.cpu / 60:.1f} ({longest.family.name}) |")
    return lines + [""]


def read_notes(path) -> dict:
    """Paper -> the findings paragraph written for it (config/benchmark/notes.yaml), if the file exists."""
    path = Path(path)
    if not path.is_file():
        return {}
    data = yaml.safe_load(path.read_text()) or {}
    return {str(k): str(v) for k, v in data.items()}


# ---------------------------------------------------------------------------------------------- written out


def _resumed(part: Part) -> str:
    return (f"; {part.resumed} rows taken from --checkpoints of an earlier run, whose time is not in these figures"
            if part.resumed else "")


def write_outputs(parts: list, out) -> tuple:
    """benchmark.md, benchmark.csv, benchmark_heatmap.png and one benchmark_pareto_paper<N>.png per paper in
    ``out`` from the rows of ``parts`` (their scenarios in paper order; :func:`merged_rows`)."""
    families, rows = merged_rows(parts)
    out = Path(out)
    csv_path = write_csv(rows, out / "benchmark.csv")
    png = draw_heatmap(rows, out / "benchmark_heatmap.png")
    pareto = {paper: draw_pareto(rows, families, paper, out / f"benchmark_pareto_paper{paper}.png").name
              for paper in sorted({f.paper for f in families})}
    if len(parts) == 1:
        p = parts[0]
        where = (f"Generated by `{p.command}` in {p.seconds / 60:.1f} min of wall time on {p.cores} cores "
                 f"({p.cpu / 60:.1f} min of CPU time; load average {p.load:.1f} at the end{_resumed(p)}")
    else:
        where = (f"Generated in {len(parts)} parts, then reported together: " + "; ".join(
            f"`{p.command}` in {p.seconds / 60:.1f} min of wall time on {p.cores} cores{f' ({p.host})' if p.host else ''}"
            f", {p.cpu / 60:.1f} min of CPU time{_resumed(p)}" for p in parts) + f" ({sum(p.cpu for p in parts) / 60:.1f} min of CPU "
            "time in all")
    text = benchmark_report(rows, families, parts[0].protocol, where, png.name,
                            read_notes(CONFIG_DIR / "benchmark" / "notes.yaml"), pareto)
    md = out / "benchmark.md"
    write_atomically(md, lambda tmp: tmp.write_text(text + "\n"))
    return md, csv_path, png


def main_benchmark(patterns=None, protocol: Protocol | None = None, out="reports", workers=None, progress=False,
                   say=None, command: str = "contouring-ros benchmark", scheduler: str | None = None,
                   save_part_to=None, host: str = "", methods=(), checkpoints=None) -> tuple:
    """Run the benchmark and write benchmark.md, benchmark.csv, benchmark_heatmap.png and one
    benchmark_pareto_paper<N>.png per paper into ``out`` (and the run as a :class:`Part` to ``save_part_to``;
    each tuned row kept in the folder ``checkpoints`` as it finishes, and those kept there taken)."""
    import resource
    protocol = protocol or Protocol()
    start = time.perf_counter()
    families = select_families(scenario_families(), patterns)
    kept = Checkpoints(checkpoints, Tuned)
    rows = run_benchmark(families, protocol, workers, progress, say, scheduler, tuple(methods or ()), kept)
    seconds = time.perf_counter() - start
    cpu = sum(resource.getrusage(who).ru_utime + resource.getrusage(who).ru_stime
              for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else math.nan
    part = Part(families, rows, protocol, seconds, cpu, os.cpu_count() or 1, command, host, load,
                tuple(methods or ()), kept.taken)
    if save_part_to:
        save_part(part, save_part_to)
    md, csv_path, png = write_outputs([part], out)
    return md, csv_path, png, seconds
