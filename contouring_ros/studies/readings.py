"""The open readings of a paper, how far each moves our figures, and the single reading closest to the paper's.

A paper leaves choices open (disturbance form and timing, initial state, units, what an ablation removes,
over what interval a figure is computed ...). ``config/readings/paper<N>.yaml`` declares them::

    paper: "000"
    cases: [paper000_b_ismc_h50_newton, ...]     # scenario files with the paper's figures (mce_um, tace_um, rms_um)
    summary: "what the measurements below say, in a few sentences (printed after the search)"
    max_combinations: 400                        # above it the search is coordinate descent, not exhaustive
    readings:
      - id: load
        open: "one line: what the paper leaves open"
        alternatives:                            # the first is the faithful default of the scenario files
          - {label: "constant at the bound (faithful)"}
          - label: "no load"
            settings: {x/plant.disturbance: {type: none}, y/plant.disturbance: {type: none}}   # sweep grid keys
            where: "paper000_b_*"                # optional glob: the cases it applies to (default: all)
          - {label: "from t = 0.3 s", from_time: 0.3}    # how the figure is computed: samples at t >= 0.3 s
    relations:                                   # the paper's relative claims: proposed / baseline in `metric`
      - {proposed: paper000_b_ismc_h50_newton, baseline: paper000_b_ismc_h50_vgccc, metric: tace}
    gaps:                                        # per case and metric: what explains the gap, measured
      - case: paper000_b_ismc_h50_newton
        metric: mce
        base: {load: 0}                          # reading id -> alternative index (the rest: faithful)
        cause: "one line: the change that removes the cause"
        remove: {settings: {...}, from_time: 0.3}    # the run with the cause removed (measure: as readings')
        after: [0.3, 1.5]                        # ours / paper with it removed lies here (tests hold it)
      - {case: ..., metric: mce, cause: "...", remove: {...}, after: [12, 16], rules_out: true}   # a cause tried
                                                 # that does NOT explain it: the figure stays in `after`
      - {case: ..., metric: mce, unexplained: "what was tried"}
      - case: paper004_saddle_eso
        metric: mce
        paper_bound: {tracking_max_um: [4.6, 15.1, 3.5]}   # the paper's own per-axis tracking figures

Sensitivity: each alternative alone (every other reading faithful), per case and metric, as ours / paper.
Search: every combination of one alternative per reading (coordinate descent from the faithful default when
there are more than ``max_combinations``), minimising the distance to all the paper's figures at once: the
largest |ln(ours / paper)| over the cases and metrics (its exp is the worst ratio), ties broken by the RMS
of ln(ours / paper). A paper bound (``paper_bound``) checks the paper's figure against its own tracking
figures: the contour error (distance to the curve) is at most the tracking error's norm, so MCE <= the norm
of the per-axis maximum tracking errors and the mean contour error <= the sum of the per-axis mean ones.
"""
from __future__ import annotations

import fnmatch
import itertools
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from .claims_file import claim_verdict
from ..core.simulation import simulate
from ..errors import ConfigError, Diverged
from ..experiment.build import build_loop
from ..experiment.files import load_experiment
from ..experiment.scenarios import CONFIG_DIR
from ..records.numbers import number, ratio
from .sweep import experiments_for, score_experiments

__all__ = ["READINGS_DIR", "METRICS", "Alternative", "Reading", "Gap", "PaperReadings", "readings_files",
           "load_readings", "Evaluator", "distance", "search", "Analysis", "analyse", "measure_gap",
           "readings_report"]

READINGS_DIR = CONFIG_DIR / "readings"
METRICS = {"mce": "mce_um", "tace": "tace_um", "rms": "rms_um"}     # our score -> the paper's key
MEASURES = {    # what a figure is computed from, per sample: how a paper may have computed its "contour error"
    "exact": "the exact contour error (distance to the whole curve)",
    "tracking_norm": "the norm of the tracking error vector |R - P|",
    "estimate": "the controller's own contour error estimate |signed estimate|",
}


@dataclass(frozen=True)
class Alternative:
    label: str
    settings: dict = field(default_factory=dict)
    where: str = "*"
    from_time: float | None = None     # None: this reading does not set the scoring interval
    measure: str | None = None         # None: this reading does not set what is measured (see MEASURES)

    def settings_for(self, case: str) -> dict:
        return dict(self.settings) if fnmatch.fnmatch(case, self.where) else {}


@dataclass(frozen=True)
class Reading:
    id: str
    open: str
    alternatives: tuple


@dataclass(frozen=True)
class Gap:
    case: str
    metric: str
    base: dict = field(default_factory=dict)
    cause: str = ""
    remove: dict = field(default_factory=dict)
    after: tuple | None = None
    unexplained: str = ""
    paper_bound: dict = field(default_factory=dict)
    rules_out: bool = False        # a change tried that leaves the figure where it was: not the cause


@dataclass
class PaperReadings:
    paper: str
    cases: list
    figures: dict                   # case -> {metric: paper value [um]}
    readings: list
    relations: list
    gaps: list
    max_combinations: int = 400
    path: Path | None = None
    excluded: set = field(default_factory=set)    # (case, metric) the paper's own figures rule out: no target
    summary: str = ""

    def choice(self, picks: dict) -> tuple:
        """A reading id -> alternative index mapping as a full choice tuple (unnamed readings: faithful)."""
        ids = [r.id for r in self.readings]
        for key, index in picks.items():
            if key not in ids:
                raise ConfigError(f"{self.path}: reading {key!r} is not declared (readings: {', '.join(ids)})")
            count = len(self.readings[ids.index(key)].alternatives)
            if not isinstance(index, int) or not 0 <= index < count:
                raise ConfigError(f"{self.path}: reading {key}: alternative {index!r} is not an index below {count}")
        return tuple(picks.get(r.id, 0) for r in self.readings)

    def describe(self, choice: tuple) -> str:
        changed = [f"{r.id}: {r.alternatives[i].label}" for r, i in zip(self.readings, choice) if i]
        return "; ".join(changed) if changed else "the faithful default"


def readings_files(directory=READINGS_DIR) -> list:
    return sorted(Path(directory).glob("paper*.yaml"))


def _mapping(value, where: str) -> dict:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise ConfigError(f"{where}: expected a mapping, got {value!r}")
    return value


def _alternative(entry, where: str) -> Alternative:
    entry = _mapping(entry, where)
    unknown = set(entry) - {"label", "settings", "where", "from_time", "measure"}
    if unknown:
        raise ConfigError(f"{where}: unknown key {sorted(unknown)[0]!r} (label, settings, where, from_time, measure)")
    if entry.get("measure") is not None and entry["measure"] not in MEASURES:
        raise ConfigError(f"{where}.measure: {entry['measure']!r} is not one of {', '.join(MEASURES)}")
    if not isinstance(entry.get("label"), str):
        raise ConfigError(f"{where}: every alternative needs a label")
    from_time = entry.get("from_time")
    if from_time is not None and (not isinstance(from_time, (int, float)) or from_time < 0):
        raise ConfigError(f"{where}: from_time must be a time >= 0 [s], got {from_time!r}")
    return Alternative(entry["label"], _mapping(entry.get("settings"), f"{where}.settings"),
                       str(entry.get("where", "*")), None if from_time is None else float(from_time),
                       entry.get("measure"))


def load_readings(paper: str, directory=READINGS_DIR) -> PaperReadings:
    """The declared readings of ``paper`` (ConfigError naming the file and key where malformed)."""
    path = Path(directory) / f"paper{paper}.yaml"
    if not path.exists():
        have = ", ".join(p.stem[5:] for p in readings_files(directory)) or "none"
        raise ConfigError(f"paper {paper}: no readings file {path} (papers with readings: {have})")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as error:
        raise ConfigError(f"{path}: not valid YAML: {str(error).splitlines()[0]}") from None
    data = _mapping(data, str(path))
    cases = data.get("cases")
    if not isinstance(cases, list) or not cases:
        raise ConfigError(f"{path}: cases: a list of scenario names with the paper's figures is needed")
    figures = {}
    for case in cases:
        if not (CONFIG_DIR / f"{case}.yaml").exists():
            raise ConfigError(f"{path}: cases: {case!r} is no scenario of {CONFIG_DIR}")
        info = load_experiment(CONFIG_DIR / f"{case}.yaml").info.get("paper", {})
        figures[case] = {m: float(info[key]) for m, key in METRICS.items() if info.get(key) is not None}
        if not figures[case]:
            raise ConfigError(f"{path}: case {case}: its scenario file gives no paper figure (mce_um, tace_um, rms_um)")
    readings = []
    for i, entry in enumerate(data.get("readings") or []):
        where = f"{path}: readings[{i}]"
        entry = _mapping(entry, where)
        alternatives = entry.get("alternatives")
        if not isinstance(entry.get("id"), str) or not isinstance(alternatives, list) or len(alternatives) < 2:
            raise ConfigError(f"{where}: needs an id and at least two alternatives (the faithful one first)")
        readings.append(Reading(entry["id"], str(entry.get("open", "")),
                                tuple(_alternative(a, f"{where}.alternatives[{j}]")
                                      for j, a in enumerate(alternatives))))
    relations = []
    for i, entry in enumerate(data.get("relations") or []):
        entry = _mapping(entry, f"{path}: relations[{i}]")
        for key in ("proposed", "baseline"):
            if entry.get(key) not in figures:
                raise ConfigError(f"{path}: relations[{i}].{key}: {entry.get(key)!r} is not one of the cases")
        if entry.get("metric") not in METRICS:
            raise ConfigError(f"{path}: relations[{i}].metric: one of {', '.join(METRICS)}")
        relations.append(entry)
    result = PaperReadings(str(data.get("paper", paper)), cases, figures, readings, relations, [],
                           int(data.get("max_combinations", 400)), path, summary=str(data.get("summary", "")))
    for i, entry in enumerate(data.get("gaps") or []):
        where = f"{path}: gaps[{i}]"
        entry = _mapping(entry, where)
        if entry.get("case") not in figures or entry.get("metric") not in figures[entry["case"]]:
            raise ConfigError(f"{where}: case {entry.get('case')!r} metric {entry.get('metric')!r}: not a case "
                              "and metric with a paper figure")
        after = entry.get("after")
        if after is not None and (not isinstance(after, list) or len(after) != 2):
            raise ConfigError(f"{where}.after: [low, high] of ours / paper with the cause removed")
        kinds = [k for k in ("remove", "unexplained", "paper_bound") if k in entry]
        if len(kinds) != 1:
            raise ConfigError(f"{where}: exactly one of remove, unexplained, paper_bound")
        result.choice(_mapping(entry.get("base"), f"{where}.base"))
        result.gaps.append(Gap(entry["case"], entry["metric"], _mapping(entry.get("base"), f"{where}.base"),
                               str(entry.get("cause", "")), _mapping(entry.get("remove"), f"{where}.remove"),
                               tuple(float(v) for v in after) if after else None, str(entry.get("unexplained", "")),
                               _mapping(entry.get("paper_bound"), f"{where}.paper_bound"),
                               bool(entry.get("rules_out", False))))
        if result.gaps[-1].rules_out and not (entry.get("remove") and after):
            raise ConfigError(f"{where}: rules_out needs remove and after")
        if result.gaps[-1].paper_bound:
            try:
                bound = paper_bound(result.gaps[-1])[0]
            except ConfigError as error:
                raise ConfigError(f"{where}: {error}") from None
            if figures[entry["case"]][entry["metric"]] > bound:
                result.excluded.add((entry["case"], entry["metric"]))
    return result


class Evaluator:
    """Our figures of every case under a choice of readings, each distinct run simulated once."""

    def __init__(self, spec: PaperReadings, workers: int | None = None):
        self.spec, self.workers = spec, workers
        self.texts = {case: load_experiment(CONFIG_DIR / f"{case}.yaml").text for case in spec.cases}
        self.cache = {}

    def run_key(self, case: str, choice: tuple, extra: dict | None = None) -> tuple:
        """(case, settings as YAML, from_time, measure): what decides one run's figures."""
        settings, from_time, measure = {}, 0.0, "exact"
        for reading, index in zip(self.spec.readings, choice):
            alternative = reading.alternatives[index]
            settings.update(alternative.settings_for(case))
            if fnmatch.fnmatch(case, alternative.where):
                from_time = from_time if alternative.from_time is None else alternative.from_time
                measure = alternative.measure or measure
        if extra:
            settings.update(extra.get("settings") or {})
            from_time = float(extra.get("from_time", from_time))
            measure = extra.get("measure", measure)
        return case, yaml.safe_dump(settings, sort_keys=True), from_time, measure

    def prefetch(self, keys) -> None:
        """Simulate every run of ``keys`` not yet measured (the exact measure vectorised on one pool; the
        others, which need every sample, one by one in this process)."""
        todo = sorted({k for k in keys if k not in self.cache})
        by_time = {}
        for key in todo:
            if key[3] != "exact":
                self.cache[key] = _measured(self.texts[key[0]], yaml.safe_load(key[1]), key[2], key[3])
                continue
            by_time.setdefault(key[2], []).append(key)
        for from_time, group in by_time.items():
            experiments = []
            for case, settings, _, _ in group:
                experiments += [e for _, e in experiments_for(self.texts[case], [yaml.safe_load(settings)],
                                                              f"readings of {case}")]
            for key, (scores, _, _) in zip(group, score_experiments(experiments, self.workers,
                                                                    from_time=from_time)):
                self.cache[key] = scores

    def figures(self, choice: tuple, extra: dict | None = None, cases=None) -> dict:
        """case -> {metric: ours [um] or None (diverged)} under ``choice``."""
        cases = cases or self.spec.cases
        keys = {case: self.run_key(case, choice, extra) for case in cases}
        self.prefetch(keys.values())
        out = {}
        for case, key in keys.items():
            scores = self.cache[key]
            out[case] = {m: (getattr(scores, m) * 1e6 if scores is not None else None)
                         for m in self.spec.figures[case]}
        return out


@dataclass(frozen=True)
class _Figures:
    mce: float
    tace: float
    rms: float


def _measured(text: str, settings: dict, from_time: float, measure: str):
    """MCE, TACE and RMS [m] of one run's samples at t >= ``from_time`` under a measure other than the exact
    contour error; None where the run diverged."""
    experiment = experiments_for(text, [settings], "readings")[0][1]
    try:
        result = simulate(build_loop(experiment))
    except Diverged:
        return None
    keep = result.time >= from_time - 1e-12
    if measure == "tracking_norm":
        values = np.linalg.norm(result.reference_position - result.position, axis=1)[keep]
    else:
        values = np.abs(result.estimate_signed)[keep]
    if not np.all(np.isfinite(values)):
        return None
    return _Figures(float(values.max()), float(values.mean()), float(np.sqrt(np.mean(values ** 2))))


def distance(spec: PaperReadings, ours: dict, every: bool = False) -> tuple:
    """(max |ln(ours / paper)|, RMS of ln(ours / paper)) over every case and metric the paper's own figures
    allow (``every``: all of them); inf if a run diverged."""
    logs = []
    for case, figures in spec.figures.items():
        for metric, theirs in figures.items():
            if (case, metric) in spec.excluded and not every:
                continue
            value = ours[case][metric]
            if value is None or value <= 0:
                return math.inf, math.inf
            logs.append(math.log(value / theirs))
    return max(abs(v) for v in logs), math.sqrt(sum(v * v for v in logs) / len(logs))


def search(spec: PaperReadings, evaluator: Evaluator) -> tuple:
    """(closest choice, its distance, how it was searched, combinations measured)."""
    sizes = [len(r.alternatives) for r in spec.readings]
    total = math.prod(sizes)
    if total <= spec.max_combinations:
        choices = list(itertools.product(*[range(n) for n in sizes]))
        evaluator.prefetch(evaluator.run_key(case, c) for c in choices for case in spec.cases)
        scored = [(distance(spec, evaluator.figures(c)), c) for c in choices]
        best = min(scored)
        return best[1], best[0], f"exhaustive: all {total} combinations", total
    current = tuple(0 for _ in sizes)
    best = distance(spec, evaluator.figures(current))
    measured, improved = {current}, True
    while improved:
        improved = False
        for i, n in enumerate(sizes):
            candidates = [current[:i] + (j,) + current[i + 1:] for j in range(n)]
            evaluator.prefetch(evaluator.run_key(case, c) for c in candidates for case in spec.cases)
            for candidate in candidates:
                measured.add(candidate)
                d = distance(spec, evaluator.figures(candidate))
                if d < best:
                    best, current, improved = d, candidate, True
    return current, best, (f"coordinate descent from the faithful default over {total} combinations "
                           f"(one reading at a time until none improves)"), len(measured)


def _ratio_text(value, theirs) -> str:
    return "diverged" if value is None else f"{number(value)} ({ratio(value, theirs, 2)}x)"


def _worst(d: float) -> str:
    return "diverged" if not math.isfinite(d) else f"{math.exp(d):.3g}"


def paper_bound(gap: Gap) -> tuple:
    """(bound [um], how it is made) that the paper's own tracking figures put on its contour error figure: the
    contour error is at most the tracking error's norm, so MCE <= the norm of the per-axis maxima and the mean
    contour error <= the sum of the per-axis means."""
    maxima, means = gap.paper_bound.get("tracking_max_um"), gap.paper_bound.get("tracking_mean_um")
    if gap.metric == "mce" and maxima:
        return math.sqrt(sum(float(v) ** 2 for v in maxima)), "the norm of its per-axis maximum tracking errors"
    if gap.metric == "tace" and means:
        return sum(float(v) for v in means), "the sum of its per-axis mean tracking errors"
    raise ConfigError(f"gap {gap.case} {gap.metric}: paper_bound needs tracking_max_um (mce) or "
                      "tracking_mean_um (tace)")


def measure_gap(spec: PaperReadings, evaluator: Evaluator, gap: Gap) -> dict:
    """What explains one case's gap, measured: the figure under ``gap.base`` and with the cause removed (or the
    paper's bound from its own tracking figures)."""
    theirs = spec.figures[gap.case][gap.metric]
    base = spec.choice(gap.base)
    before = evaluator.figures(base, cases=[gap.case])[gap.case][gap.metric]
    out = {"theirs": theirs, "before": before, "base": spec.describe(base)}
    if gap.remove:
        after = evaluator.figures(base, gap.remove, cases=[gap.case])[gap.case][gap.metric]
        out["after"] = after
        out["holds"] = (gap.after is None or (after is not None
                                              and gap.after[0] <= after / theirs <= gap.after[1]))
        out["text"] = (("not the cause: " if gap.rules_out else "")
                       + f"{gap.cause}: {_ratio_text(before, theirs)} -> {_ratio_text(after, theirs)}"
                       + ("" if out["holds"] else f" (stated {gap.after[0]:g}-{gap.after[1]:g}x: NOT REPRODUCED)"))
    elif gap.paper_bound:
        bound, how = paper_bound(gap)
        out["bound"], out["holds"] = bound, theirs > bound
        verdict = "the paper's own table is inconsistent" if theirs > bound else "within the bound"
        out["text"] = (f"{gap.cause + ': ' if gap.cause else ''}the paper's {gap.metric.upper()} {theirs:g} um exceeds "
                       f"{bound:.3g} um, {how}, which bounds any contour error: {verdict}"
                       if theirs > bound else f"paper's {theirs:g} um is within {bound:.3g} um ({how})")
    else:
        out["holds"], out["text"] = True, f"unexplained: {gap.unexplained}"
    return out


@dataclass
class Analysis:
    spec: PaperReadings
    default: dict
    default_distance: tuple
    sensitivity: list              # (reading, alternative index, figures)
    closest: tuple
    closest_figures: dict
    closest_distance: tuple
    how: str
    measured: int
    relations: list                # (relation, paper ratio, default ratio, closest ratio)
    gaps: list                     # (Gap, measured dict)


def _relation_ratio(figures: dict, relation: dict):
    metric = relation["metric"]
    p, b = figures[relation["proposed"]].get(metric), figures[relation["baseline"]].get(metric)
    return None if p is None or not b else p / b


def analyse(paper: str, workers: int | None = None, directory=READINGS_DIR) -> Analysis:
    """Sensitivity, search, relative claims and gap explanations of one paper's readings."""
    spec = load_readings(paper, directory)
    evaluator = Evaluator(spec, workers)
    default_choice = tuple(0 for _ in spec.readings)
    sensitivity_choices = [(i, j, default_choice[:i] + (j,) + default_choice[i + 1:])
                           for i, r in enumerate(spec.readings) for j in range(1, len(r.alternatives))]
    evaluator.prefetch(evaluator.run_key(case, c) for _, _, c in sensitivity_choices for case in spec.cases)
    default = evaluator.figures(default_choice)
    sensitivity = [(spec.readings[i], j, evaluator.figures(c)) for i, j, c in sensitivity_choices]
    closest, closest_distance, how, measured = search(spec, evaluator)
    closest_figures = evaluator.figures(closest)
    relations = [(r, spec.figures[r["proposed"]][r["metric"]] / spec.figures[r["baseline"]][r["metric"]],
                  _relation_ratio(default, r), _relation_ratio(closest_figures, r)) for r in spec.relations]
    gaps = [(g, measure_gap(spec, evaluator, g)) for g in spec.gaps]
    return Analysis(spec, default, distance(spec, default), sensitivity, closest, closest_figures,
                    closest_distance, how, measured, relations, gaps)


def readings_report(analysis: Analysis) -> str:
    """The Markdown section of one paper: readings, sensitivity, search, per-case gaps, relative claims."""
    spec = analysis.spec
    columns = [(case, metric) for case in spec.cases for metric in spec.figures[case]]
    short = {case: case.removeprefix(f"paper{spec.paper}_") for case in spec.cases}
    lines = [f"#### Paper {spec.paper}: open readings", "",
             f"Declared in `config/readings/paper{spec.paper}.yaml`; the first alternative of each is the "
             "scenario files' faithful reading.", "", "| reading | what the paper leaves open | alternatives |",
             "|---|---|---|"]
    for r in spec.readings:
        lines.append(f"| {r.id} | {r.open} | " + "; ".join(f"({j}) {a.label}" for j, a in
                                                         enumerate(r.alternatives)) + " |")
    lines += ["", "Sensitivity: ours / paper with each alternative alone (every other reading faithful).", "",
              "| reading: alternative | " + " | ".join(f"{short[c]} {m.upper()}" for c, m in columns) + " | worst |",
              "|---|" + "---:|" * (len(columns) + 1)]

    def row(label, figures, d):
        cells = ["-" if figures[c][m] is None else f"{figures[c][m] / spec.figures[c][m]:.2g}" for c, m in columns]
        return f"| {label} | " + " | ".join(cells) + f" | {_worst(d[0])} |"

    lines.append(row("faithful default", analysis.default, analysis.default_distance))
    for reading, j, figures in analysis.sensitivity:
        lines.append(row(f"{reading.id}: ({j}) {reading.alternatives[j].label}", figures, distance(spec, figures)))
    dd, cd = analysis.default_distance, analysis.closest_distance
    targets = len(columns) - len(spec.excluded)
    ruled_out = (f" ({len(spec.excluded)} figures the paper's own tracking figures rule out are no target: "
                 + ", ".join(f"{short[c]} {m.upper()}" for c, m in sorted(spec.excluded)) + ")"
                 if spec.excluded else "")
    da, ca = distance(spec, analysis.default, True), distance(spec, analysis.closest_figures, True)
    every = (lambda d: f"; over all {len(columns)} figures {_worst(d[0])}") if spec.excluded else (lambda d: "")
    lines += ["", f"Search ({analysis.how}; {analysis.measured} measured) for the single reading closest to all "
              f"{targets} target figures at once{ruled_out}, minimising the largest |ln(ours / paper)| "
              "(ties: its RMS).",
              "", f"- faithful default: worst ratio {_worst(dd[0])}, RMS |ln ratio| {dd[1]:.3g}{every(da)}",
              f"- closest reading: {spec.describe(analysis.closest)}: worst ratio {_worst(cd[0])}, "
              f"RMS |ln ratio| {cd[1]:.3g}{every(ca)}", *(["", spec.summary] if spec.summary else []), "",
              "| case | metric | paper | ours, default | ours, closest | "
              "what explains the rest of the gap (measured) |", "|---|---|---:|---:|---:|---|"]
    explained = {}
    for gap, measured in analysis.gaps:
        explained.setdefault((gap.case, gap.metric), []).append(measured["text"] + (
            f" [from: {measured['base']}]" if "before" in measured and gap.remove else ""))
    for case, metric in columns:
        theirs = spec.figures[case][metric]
        why = "; ".join(explained.get((case, metric), [])) or "not stated"
        lines.append(f"| {short[case]} | {metric.upper()} | {theirs:g} | "
                     f"{_ratio_text(analysis.default[case][metric], theirs)} | "
                     f"{_ratio_text(analysis.closest_figures[case][metric], theirs)} | {why} |")
    if analysis.relations:
        lines += ["", "The paper's relative claims (proposed / baseline; verdicts as in `config/claims/`: holds where ours "
                  "has at least 3/4 of the paper's cut):", "",
                  "| proposed | baseline | metric | paper | default | verdict | closest | verdict |",
                  "|---|---|---|---:|---:|---|---:|---|"]
        for r, theirs, default, closest in analysis.relations:
            lines.append(f"| {short[r['proposed']]} | {short[r['baseline']]} | {r['metric'].upper()} | {number(theirs)} | "
                         f"{number(default)} | {claim_verdict(default, theirs)} | {number(closest)} | {claim_verdict(closest, theirs)} |")
    return "\n".join(lines)
