"""Each paper's central claims, tested under the paper's own reading and where the claim's mechanism acts.

A paper's claims live in ``config/claims/paper<N>.yaml``::

    paper: "000"
    title: "Authors, short title"
    readings: ["every reading the scenario files choose where the paper is silent", ...]
    claims:
      - id: newton_ccc_vs_vgccc          # the map is reports/maps/paper000_<id>.png
        claim: "one line: what the paper claims"
        paper_figure: "the paper's own numbers, and where"
        paper_ratio: 0.069               # proposed / baseline in the paper, in `metric`; null: no figure
                                         # (the claim is only that it lowers: verdict lowers / does not lower)
        metric: tace                     # mce | tace | rms | estimation_max | estimation_rms
        from_time: 0.0                   # score the samples at t >= from_time [s] (0: the whole run)
        faithful: {proposed: <scenario>, baseline: <scenario>}   # the paper's experiment, faithful reading
        mechanism: {proposed: <scenario>, baseline: <scenario>}  # where the claim's mechanism acts
        adds: "one line: what the mechanism scenario adds beyond the paper"
        decisive:                        # the parameters that decide the claim, each scaled x0.7 and x1.4
          - {label: "plant gain K (K_v = K kp)", keys: [x/plant.gain, y/plant.gain]}
        expected: {faithful_ratio: 0.52, faithful_interval: [0.5, 0.54], mechanism_ratio: 0.21,
                   mechanism_interval: [0.2, 0.22], ideal_faithful_ratio: 0.5, ideal_mechanism_ratio: 0.2,
                   tolerance: 0.1}
        verdict: {faithful: "holds weaker", mechanism: "holds"}
        reason: "at most three sentences"
        maps:
          - pair: mechanism
            x: {label: "...", keys: [schedule.duration], values: [...]}
            y: {label: "...", keys: [x/plant.saturation, y/plant.saturation], values: [...]}
            # an axis with `only: proposed` (or baseline) sets its keys in that file alone, e.g. ccc.kp
    ccc_helps:
      - {scenario: <scenario>, without: {/ccc: {type: none}}, metric: tace, from_time: 0.0, factor: 2.0}

Scenario names are files of ``config/``. A ratio is proposed / baseline of the claim's metric (lower: the
proposed method better). :func:`verdict` turns a ratio and the paper's into a verdict.

Machine and uncertainty. A claim is measured on the *realistic* machine of :mod:`contouring_ros.studies.machine`
(encoder, noise, one sample of delay, velocity from the encoder, an actuator limit of 2x the proposed file's
peak command where the file states none): the machine is made from the proposed file (its ideal run's peak
command) and put under BOTH files of the pair. The ratio is the median over :data:`DRAWS` paired draws (draw
j, :func:`contouring_ros.studies.machine.draw_settings`: noise seeds and +-:data:`MISMATCH` on every plant parameter,
the same draw for both files) with the 2.5-97.5 percentile interval of the per-draw ratios;
:func:`interval_verdict` gives a verdict only where the whole interval has one (else 'undecided'). The ideal
machine's ratio (no imperfections, no draws) is kept beside it. Sensitivity: each ``decisive`` entry's keys
are scaled x0.7 and x1.4 in both files alike (on the realistic machine, no draw: seed 0, no mismatch), and
:func:`robustness` says whether the verdict of the median ratio stays the same ('robust') or flips
('knife-edge', naming where). ``expected`` and ``verdict`` are what the tests hold the measurement to
(the realistic medians, intervals and interval verdicts; the ideal ratios). A map sweeps the pair's two files alike over one or
two variables (grid keys as in :mod:`contouring_ros.studies.sweep`; a variable with several keys sets them all) and
draws proposed / baseline MCE and TACE with the contour where the paper's ratio is reached.
"""
from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from ..experiment.files import load_experiment
from ..experiment.ros_yaml import read_yaml
from ..errors import ConfigError
from ..records.outputs import write_atomically
from .executors import pool as executor
from ..experiment.scenarios import CONFIG_DIR
from .sweep import experiments_for, score_experiments
from ..experiment.settings import grid_key_location
from .machine import draw_settings, machine_settings
from .outcomes import run_outcomes
from .summaries import interval

__all__ = ["VERDICTS", "METRICS", "DRAWS", "MISMATCH", "SCALES", "verdict", "interval_verdict", "robustness",
           "Decisive", "Plan", "plan_pair", "Measured", "peak_commands", "Pair", "MapAxis", "RegimeMap", "Claim", "CCCHelps", "PaperClaims",
           "claim_files", "load_claims", "ScenarioScores", "ClaimResult", "evaluate", "ccc_helps_scores",
           "map_ratios", "draw_map", "claims_report", "write_claims_report"]

VERDICTS = ("holds", "holds weaker", "does not hold", "reversed", "not testable", "undecided", "lowers",
            "does not lower")
DRAWS = 8               # paired draws per claim pair (noise seeds, model mismatch, disturbance phase)
MISMATCH = 0.1          # model mismatch of a draw: each plant parameter x U(1 - this, 1 + this)
SCALES = (0.7, 1.4)     # the sensitivity factors of each decisive parameter
METRICS = {"mce": "MCE", "tace": "TACE", "rms": "RMS", "estimation_max": "estimation deviation max",
           "estimation_rms": "estimation deviation RMS"}
VERDICT_RULE = ("A ratio is proposed / baseline in the claim's metric (lower: the proposed method better); r is "
                "ours, p the paper's. Verdict: **holds** when 1 - r >= 0.75 (1 - p) (our reduction reaches three "
                "quarters of the paper's), **holds weaker** when r < 0.95, **does not hold** when 0.95 <= r <= "
                "1.05, **reversed** when r > 1.05, **not testable** when no pair of runs can test it. Where the "
                "paper gives no figure (paper ratio null, shown as -) the verdict is only **lowers** (r < 1) or "
                "**does not lower** (r >= 1). Our r is the median over the paired draws on the realistic machine, "
                "with the 2.5-97.5% interval [lo, hi] of the per-draw ratios; the verdict is given only where lo and "
                "hi have the same verdict (the interval crosses no threshold; with no paper figure: lowers where hi < "
                "1, does not lower where lo >= 1), else **undecided**. Sensitivity: the verdict of the seed-0 ratio "
                "(realistic machine, no mismatch) with each decisive parameter x0.7 and x1.4 (both files alike); "
                "**robust** when all equal the unscaled seed-0 verdict, else **knife-edge** (naming the flips).")


def verdict(ratio: float | None, paper_ratio: float | None) -> str:
    """The verdict on a claim whose paper reports ``paper_ratio`` (proposed / baseline; None: no figure, the
    claim is only that it lowers) when we measure ``ratio`` (see VERDICT_RULE); ``None`` (no measurement) is
    'not testable'."""
    if ratio is None or not math.isfinite(ratio):
        return "not testable"
    if paper_ratio is None:
        return "lowers" if ratio < 1.0 else "does not lower"
    if 1.0 - ratio >= 0.75 * (1.0 - paper_ratio):
        return "holds"
    if ratio < 0.95:
        return "holds weaker"
    if ratio <= 1.05:
        return "does not hold"
    return "reversed"


def interval_verdict(low: float | None, high: float | None, paper_ratio: float | None) -> str:
    """The verdict of an interval [low, high] of ratios: the verdict both ends share (the verdict is monotone in
    the ratio, so every ratio between has it too), else 'undecided'; no interval is 'not testable'."""
    if low is None or high is None or not (math.isfinite(low) and math.isfinite(high)):
        return "not testable"
    at_low, at_high = verdict(low, paper_ratio), verdict(high, paper_ratio)
    return at_low if at_low == at_high else "undecided"


def robustness(reference: str, scaled: dict) -> tuple:
    """('robust' or 'knife-edge' or 'not testable', the flips): ``scaled`` maps (label, factor) to the verdict
    there; a flip is an entry whose verdict differs from ``reference`` ('label x0.7: holds weaker')."""
    if reference == "not testable" or not scaled:
        return "not testable", []
    flips = [f"{label} x{factor:g}: {given}" for (label, factor), given in scaled.items() if given != reference]
    return ("knife-edge" if flips else "robust"), flips


@dataclass(frozen=True)
class Decisive:
    """A parameter that decides a claim: its grid keys, scaled alike (x :data:`SCALES`) in the pair's files."""

    label: str
    keys: tuple
    only: str | None = None     # 'proposed' or 'baseline': scale the keys in that file alone


@dataclass(frozen=True)
class Pair:
    proposed: str
    baseline: str


@dataclass(frozen=True)
class MapAxis:
    label: str
    keys: tuple
    values: tuple
    only: str | None = None     # 'proposed' or 'baseline': set the keys in that file alone (e.g. a CCC gain)


@dataclass(frozen=True)
class RegimeMap:
    pair: str                   # 'mechanism' or 'faithful'
    x: MapAxis
    y: MapAxis | None = None


@dataclass(frozen=True)
class Claim:
    paper: str
    id: str
    claim: str
    paper_figure: str
    paper_ratio: float | None
    metric: str
    from_time: float
    faithful: Pair | None
    mechanism: Pair | None
    expected: dict
    verdict: dict
    reason: str
    maps: tuple = ()
    adds: str = ""
    decisive: tuple = ()

    def pair(self, reading: str) -> Pair | None:
        return self.faithful if reading == "faithful" else self.mechanism

    def map_path(self, index: int, directory) -> Path:
        suffix = "" if index == 0 else f"_{index + 1}"
        return Path(directory) / "maps" / f"paper{self.paper}_{self.id}{suffix}.png"


@dataclass(frozen=True)
class CCCHelps:
    """A CCC lowers ``metric`` on ``scenario`` by ``factor`` against the same run with ``without`` applied."""

    paper: str
    scenario: str
    without: dict
    metric: str
    from_time: float
    factor: float


@dataclass(frozen=True)
class PaperClaims:
    paper: str
    title: str
    readings: tuple
    claims: tuple
    ccc_helps: tuple
    path: str = ""


# ---------------------------------------------------------------------------------------------- loading


def claim_files(directory=None) -> list:
    return sorted(Path(directory or CONFIG_DIR / "claims").glob("paper???.yaml"))


class _Reader:
    """Typed access to a claims file's mappings; every mistake is a one-line ConfigError naming the key."""

    def __init__(self, path):
        self.path = str(path)

    def fail(self, where: str, message: str):
        raise ConfigError(f"{self.path}: {where}: {message}")

    def get(self, data, key: str, where: str, kind, default=...):
        if not isinstance(data, dict):
            self.fail(where, "expected a mapping")
        if key not in data:
            if default is ...:
                self.fail(f"{where}.{key}" if where else key, "missing")
            return default
        value = data[key]
        if kind is float:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                self.fail(f"{where}.{key}" if where else key, f"expected a number, got {value!r}")
            return float(value)
        if not isinstance(value, kind):
            self.fail(f"{where}.{key}" if where else key, f"expected {getattr(kind, '__name__', kind)}, got {value!r}")
        return value

    def scenario(self, name, where: str) -> str:
        if not isinstance(name, str) or not (CONFIG_DIR / f"{name}.yaml").is_file():
            self.fail(where, f"no scenario file config/{name}.yaml")
        return name

    def pair(self, data, key: str, where: str) -> Pair | None:
        given = self.get(data, key, where, (dict, type(None)), None)
        if given is None:
            return None
        return Pair(*(self.scenario(self.get(given, side, f"{where}.{key}", str), f"{where}.{key}.{side}")
                      for side in ("proposed", "baseline")))

    def metric(self, data, where: str) -> str:
        metric = self.get(data, "metric", where, str)
        if metric not in METRICS:
            self.fail(f"{where}.metric", f"expected one of {', '.join(METRICS)}, got {metric!r}")
        return metric

    def axis(self, data, where: str) -> MapAxis:
        keys = self.get(data, "keys", where, list)
        values = self.get(data, "values", where, list)
        if not keys or not all(isinstance(k, str) for k in keys):
            self.fail(f"{where}.keys", "expected a list of grid keys")
        if len(values) < 2:
            self.fail(f"{where}.values", "expected at least two values")
        only = self.get(data, "only", where, (str, type(None)), None)
        if only not in (None, "proposed", "baseline"):
            self.fail(f"{where}.only", f"expected proposed or baseline, got {only!r}")
        return MapAxis(self.get(data, "label", where, str), tuple(keys), tuple(values), only)


def load_claims(path) -> PaperClaims:
    """Read and check a claims file (see the module docstring)."""
    read = _Reader(path)
    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as error:
        raise ConfigError(f"{path}: cannot be read: {str(error).splitlines()[0]}") from None
    paper = str(read.get(data, "paper", "", (str, int)))
    claims = []
    for i, c in enumerate(read.get(data, "claims", "", list)):
        where = f"claims[{i}]"
        maps = []
        for j, m in enumerate(read.get(c, "maps", where, list, [])):
            at = f"{where}.maps[{j}]"
            pair = read.get(m, "pair", at, str, "mechanism")
            if pair not in ("mechanism", "faithful"):
                read.fail(f"{at}.pair", f"expected mechanism or faithful, got {pair!r}")
            y = read.get(m, "y", at, (dict, type(None)), None)
            maps.append(RegimeMap(pair, read.axis(read.get(m, "x", at, dict), f"{at}.x"),
                                  read.axis(y, f"{at}.y") if y is not None else None))
        expected = read.get(c, "expected", where, dict)
        for key in ("faithful_ratio", "mechanism_ratio", "ideal_faithful_ratio", "ideal_mechanism_ratio", "tolerance"):
            read.get(expected, key, f"{where}.expected", (float, int, type(None)), None)
        for key in ("faithful_interval", "mechanism_interval"):
            given = read.get(expected, key, f"{where}.expected", (list, type(None)), None)
            if given is not None and (len(given) != 2 or not all(isinstance(v, (int, float)) for v in given)):
                read.fail(f"{where}.expected.{key}", f"expected [low, high], got {given!r}")
        decisive = []
        for j, d in enumerate(read.get(c, "decisive", where, list, [])):
            at = f"{where}.decisive[{j}]"
            keys = read.get(d, "keys", at, list)
            if not keys or not all(isinstance(k, str) for k in keys):
                read.fail(f"{at}.keys", "expected a list of grid keys")
            only = read.get(d, "only", at, (str, type(None)), None)
            if only not in (None, "proposed", "baseline"):
                read.fail(f"{at}.only", f"expected proposed or baseline, got {only!r}")
            decisive.append(Decisive(read.get(d, "label", at, str), tuple(keys), only))
        paper_ratio = read.get(c, "paper_ratio", where, (float, int, type(None)))
        if paper_ratio is not None:
            paper_ratio = read.get(c, "paper_ratio", where, float)
        verdicts = read.get(c, "verdict", where, dict)
        for reading, given in verdicts.items():
            if reading not in ("faithful", "mechanism") or given not in VERDICTS:
                read.fail(f"{where}.verdict.{reading}", f"expected faithful/mechanism: one of {', '.join(VERDICTS)}")
        claims.append(Claim(
            paper=paper, id=read.get(c, "id", where, str), claim=read.get(c, "claim", where, str),
            paper_figure=read.get(c, "paper_figure", where, str),
            paper_ratio=paper_ratio, metric=read.metric(c, where),
            from_time=read.get(c, "from_time", where, float, 0.0),
            faithful=read.pair(c, "faithful", where), mechanism=read.pair(c, "mechanism", where),
            expected=expected, verdict=verdicts, reason=read.get(c, "reason", where, str), maps=tuple(maps),
            adds=read.get(c, "adds", where, str, ""), decisive=tuple(decisive)))
    helps = []
    for i, h in enumerate(read.get(data, "ccc_helps", "", list, [])):
        where = f"ccc_helps[{i}]"
        helps.append(CCCHelps(paper, read.scenario(read.get(h, "scenario", where, str), f"{where}.scenario"),
                              read.get(h, "without", where, dict), read.metric(h, where),
                              read.get(h, "from_time", where, float, 0.0), read.get(h, "factor", where, float)))
    return PaperClaims(paper, read.get(data, "title", "", str), tuple(str(r) for r in read.get(data, "readings", "", list)),
                       tuple(claims), tuple(helps), str(path))


# ---------------------------------------------------------------------------------------------- measuring


def _experiment(name: str, settings: dict | None = None):
    experiment = load_experiment(CONFIG_DIR / f"{name}.yaml")
    if not settings:
        return experiment
    return experiments_for(experiment.text, [settings], where=name)[0][1]


@dataclass
class ScenarioScores:
    """Scores of scenarios (with optional settings applied) at the start times asked for, computed once."""

    workers: int | None = None
    cache: dict = field(default_factory=dict)
    scheduler: str | None = None     # a Dask scheduler's address (contouring_ros.studies.executors), else local processes

    @staticmethod
    def _key(name, settings, from_time):
        return name, repr(sorted((settings or {}).items())), float(from_time)

    def need(self, requests: list) -> None:
        """Simulate every (scenario, settings, from_time) not yet scored, on the process pool."""
        missing = {}
        for name, settings, from_time in requests:
            key = self._key(name, settings, from_time)
            if key not in self.cache:
                missing[key] = (name, settings, from_time)
        by_time = {}
        for key, (name, settings, from_time) in missing.items():
            by_time.setdefault(float(from_time), []).append((key, _experiment(name, settings)))
        for from_time, runs in by_time.items():
            results = score_experiments([e for _, e in runs], self.workers, from_time=from_time, batch=1,
                                        scheduler=self.scheduler)
            for (key, _), (scores, _, failure) in zip(runs, results):
                self.cache[key] = (scores, failure)

    def get(self, name: str, from_time: float, settings: dict | None = None):
        key = self._key(name, settings, from_time)
        if key not in self.cache:
            self.need([(name, settings, from_time)])
        return self.cache[key]


def _scenario_data(name: str) -> dict:
    return read_yaml((CONFIG_DIR / f"{name}.yaml").read_text(), name)


def _peak_command(name: str, from_time: float) -> tuple:
    """The largest |command| per axis of the scenario's ideal run (() where it diverged)."""
    outcome = run_outcomes(_scenario_data(name), {}, [{}], from_time, name)[0]
    return outcome.peak_command if outcome.ok else ()


def peak_commands(names: list, from_time: dict, workers: int | None = None, scheduler: str | None = None) -> dict:
    """name -> its ideal run's peak command per axis, on a process pool (or the Dask cluster at ``scheduler``)."""
    names = list(dict.fromkeys(names))
    if not names:
        return {}
    with executor(min(len(names), workers) if workers else None, scheduler) as (pool, _):
        return dict(zip(names, pool.map(_peak_command, names, [from_time[n] for n in names])))


def _scaled(value, factor: float, where: str):
    if isinstance(value, bool) or value is None:
        raise ConfigError(f"{where}: no number to scale (the file leaves it to a default): name a key it sets")
    if isinstance(value, list):
        return [_scaled(v, factor, where) for v in value]
    if not isinstance(value, (int, float)):
        raise ConfigError(f"{where}: {value!r} is not a number to scale")
    return float(value) * factor


@dataclass(frozen=True)
class Plan:
    """The settings of every run of one claim pair (reading): the machine made from the proposed file, the
    paired draws, the seed-0 run and the decisive parameters' scaled runs, per file (proposed, baseline)."""

    machine: dict
    draws: tuple        # (proposed settings, baseline settings) per draw
    nominal: tuple      # (proposed, baseline): the realistic machine, seed 0, no mismatch
    scaled: dict        # (label, factor) -> (proposed, baseline)


def plan_pair(claim: "Claim", pair: Pair, peak: tuple, draws: int = DRAWS, machine: str = "realistic",
              sensitivity: bool = True) -> Plan:
    data = (_scenario_data(pair.proposed), _scenario_data(pair.baseline))
    made = machine_settings(data[0], machine, peak)
    if machine == "ideal":
        runs = ((dict(), dict()),)
    else:
        runs = tuple(tuple(dict(made, **draw_settings(d, j, MISMATCH)) for d in data) for j in range(draws))
    scaled = {}
    if sensitivity:
        for entry in claim.decisive:
            for factor in SCALES:
                both = []
                for side, name in (("proposed", pair.proposed), ("baseline", pair.baseline)):
                    settings = dict(made)
                    if entry.only in (None, side):
                        for key in entry.keys:
                            base = made.get(key, _base_value(name, key))
                            settings[key] = _scaled(base, factor, f"claims {claim.paper}/{claim.id}: decisive "
                                                                  f"{entry.label!r}: {name} {key}")
                    both.append(settings)
                scaled[(entry.label, factor)] = tuple(both)
    return Plan(made, runs, (dict(made), dict(made)), scaled)


@dataclass(frozen=True)
class Measured:
    """One pair's scores: ideal (proposed, baseline), per draw, seed 0 and scaled (same shapes)."""

    ideal: tuple
    draws: tuple
    nominal: tuple
    scaled: dict
    machine: dict


def _ratio_of(pair, metric: str):
    if not pair or pair[0] is None or pair[1] is None:
        return None
    proposed, baseline = getattr(pair[0], metric), getattr(pair[1], metric)
    if not baseline or not math.isfinite(proposed) or not math.isfinite(baseline):
        return None
    return proposed / baseline


@dataclass(frozen=True)
class ClaimResult:
    claim: Claim
    measured: dict      # reading -> Measured (or None)

    @property
    def scores(self) -> dict:
        """reading -> the ideal machine's (proposed Scores, baseline Scores)."""
        return {reading: m.ideal for reading, m in self.measured.items() if m is not None}

    def draw_ratios(self, reading: str, metric: str | None = None) -> list:
        m = self.measured.get(reading)
        return [] if m is None else [_ratio_of(d, metric or self.claim.metric) for d in m.draws]

    def value(self, reading: str, side: int, metric: str | None = None):
        """The median of the side's metric over the draws (realistic machine)."""
        m = self.measured.get(reading)
        if m is None:
            return None
        values = [getattr(d[side], metric or self.claim.metric) for d in m.draws if d[side] is not None]
        median = interval(values)[0]
        return None if not math.isfinite(median) else median

    def ideal_value(self, reading: str, side: int, metric: str | None = None):
        m = self.measured.get(reading)
        if m is None or m.ideal[side] is None:
            return None
        return getattr(m.ideal[side], metric or self.claim.metric)

    def interval(self, reading: str, metric: str | None = None) -> tuple:
        """(median, 2.5%, 97.5%) of the per-draw ratios (None each where no draw has one)."""
        ratios = [r for r in self.draw_ratios(reading, metric) if r is not None]
        if not ratios:
            return None, None, None
        return interval(ratios)

    def ratio(self, reading: str, metric: str | None = None):
        return self.interval(reading, metric)[0]

    def ideal_ratio(self, reading: str, metric: str | None = None):
        m = self.measured.get(reading)
        return None if m is None else _ratio_of(m.ideal, metric or self.claim.metric)

    def verdict(self, reading: str) -> str:
        _, low, high = self.interval(reading)
        return interval_verdict(low, high, self.claim.paper_ratio)

    def ideal_verdict(self, reading: str) -> str:
        return verdict(self.ideal_ratio(reading), self.claim.paper_ratio)

    def failures(self, reading: str) -> int:
        """Draws without a ratio (a run diverged)."""
        return sum(1 for r in self.draw_ratios(reading) if r is None)

    def nominal_ratio(self, reading: str):
        m = self.measured.get(reading)
        return None if m is None else _ratio_of(m.nominal, self.claim.metric)

    def scaled_verdicts(self, reading: str) -> dict:
        m = self.measured.get(reading)
        if m is None:
            return {}
        return {key: verdict(_ratio_of(pair, self.claim.metric), self.claim.paper_ratio)
                for key, pair in m.scaled.items()}

    def scaled_ratios(self, reading: str) -> dict:
        m = self.measured.get(reading)
        return {} if m is None else {key: _ratio_of(pair, self.claim.metric) for key, pair in m.scaled.items()}

    def robustness(self, reading: str) -> tuple:
        return robustness(verdict(self.nominal_ratio(reading), self.claim.paper_ratio), self.scaled_verdicts(reading))


def evaluate(claims: list, scores: ScenarioScores | None = None, draws: int = DRAWS, machine: str = "realistic",
             sensitivity: bool = True) -> list:
    """A ClaimResult per claim: its pairs simulated under both readings on the ideal machine and on
    ``machine`` with ``draws`` paired draws, seed 0 and (with ``sensitivity``) the decisive parameters scaled;
    every distinct run once, on the process pool."""
    scores = scores or ScenarioScores()
    pairs = [(c, reading, c.pair(reading)) for c in claims for reading in ("faithful", "mechanism") if c.pair(reading)]
    times = {}
    for c, _, pair in pairs:
        times.setdefault(pair.proposed, c.from_time)
    peaks = peak_commands([pair.proposed for _, _, pair in pairs], times, scores.workers, scores.scheduler) \
        if machine != "ideal" else {}
    plans = {(c.id, reading): plan_pair(c, pair, peaks.get(pair.proposed, ()), draws, machine, sensitivity)
             for c, reading, pair in pairs}
    requests = []
    for c, reading, pair in pairs:
        plan = plans[(c.id, reading)]
        names = (pair.proposed, pair.baseline)
        requests += [(name, None, c.from_time) for name in names]
        for both in list(plan.draws) + [plan.nominal] + list(plan.scaled.values()):
            requests += [(name, settings, c.from_time) for name, settings in zip(names, both)]
    scores.need(requests)

    def got(name, settings, from_time):
        return scores.get(name, from_time, settings or None)[0]

    out = []
    for c in claims:
        measured = {}
        for reading in ("faithful", "mechanism"):
            pair = c.pair(reading)
            if not pair:
                continue
            plan = plans[(c.id, reading)]
            names = (pair.proposed, pair.baseline)
            measured[reading] = Measured(
                ideal=tuple(got(n, None, c.from_time) for n in names),
                draws=tuple(tuple(got(n, s, c.from_time) for n, s in zip(names, both)) for both in plan.draws),
                nominal=tuple(got(n, s, c.from_time) for n, s in zip(names, plan.nominal)),
                scaled={key: tuple(got(n, s, c.from_time) for n, s in zip(names, both))
                        for key, both in plan.scaled.items()},
                machine=plan.machine)
        out.append(ClaimResult(c, measured))
    return out


def ccc_helps_scores(entry: CCCHelps, scores: ScenarioScores | None = None) -> tuple:
    """(metric with the CCC, metric without it) for a CCCHelps entry."""
    scores = scores or ScenarioScores()
    with_ccc = scores.get(entry.scenario, entry.from_time)[0]
    without = scores.get(entry.scenario, entry.from_time, entry.without)[0]
    return (getattr(with_ccc, entry.metric) if with_ccc else math.nan,
            getattr(without, entry.metric) if without else math.nan)


# ---------------------------------------------------------------------------------------------- regime maps


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
        text = _experiment(name).text
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


def _base_value(name: str, key: str):
    """The value a grid key has in a scenario file (None where the file leaves it to a default)."""
    target, path = grid_key_location(read_yaml((CONFIG_DIR / f"{name}.yaml").read_text(), name), key)
    for part in path:
        if not isinstance(target, dict) or part not in target:
            return None
        target = target[part]
    return target


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
    here = (_nearest(spec.x.values, _base_value(pair.proposed, spec.x.keys[0])),
            _nearest(spec.y.values, _base_value(pair.proposed, spec.y.keys[0])) if spec.y else 0)
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


# ---------------------------------------------------------------------------------------------- report


def _um(value, metric: str) -> str:
    return "-" if value is None else f"{value * 1e6:.3g}"


def _ratio(value) -> str:
    return "-" if value is None or not math.isfinite(value) else f"{value:.3g}"


def _paper_ratio(value) -> str:
    return "-" if value is None else f"{value:.3g}"


def _files(pair: Pair | None) -> str:
    return "-" if pair is None else f"`{pair.proposed}` vs `{pair.baseline}`"


def _with_interval(result: "ClaimResult", reading: str) -> str:
    median, low, high = result.interval(reading)
    if median is None:
        return "-"
    failed = result.failures(reading)
    digits = 3 if f"{low:.3g}" != f"{high:.3g}" else 6     # a narrow interval (an inert term) shown as it is
    return f"{median:.{digits}g} [{low:.{digits}g}, {high:.{digits}g}]" + (f" ({failed} draws diverged)" if failed else "")


def _sensitivity(result: "ClaimResult", reading: str) -> str:
    word, flips = result.robustness(reading)
    if word == "not testable":
        return word if result.claim.decisive else "-"
    return word + (f" ({'; '.join(flips)})" if flips else "")


def paper_section(paper: PaperClaims, results: list, maps: dict, helps: list, directory, draws: int = DRAWS) -> str:
    lines = [f"## Paper {paper.paper}: {paper.title}", ""]
    for result in results:
        c = result.claim
        name = METRICS[c.metric] + (f" from t = {c.from_time:g} s" if c.from_time else ", whole run")
        lines += [f"### {c.id}: {c.claim}", "",
                  f"| | ratio ({name}): median [95% interval] of {draws} draws, realistic machine | proposed [um] | "
                  "baseline [um] | verdict | ideal machine: ratio, verdict | x0.7 / x1.4 | files |",
                  "|---|---:|---:|---:|---|---|---|---|",
                  f"| paper | {_paper_ratio(c.paper_ratio)} | | | | | | {c.paper_figure} |"]
        for reading, label in (("faithful", "ours, faithful reading"), ("mechanism", "ours, where the mechanism acts")):
            lines.append(f"| {label} | {_with_interval(result, reading)} | {_um(result.value(reading, 0), c.metric)} | "
                         f"{_um(result.value(reading, 1), c.metric)} | **{result.verdict(reading)}** | "
                         f"{_ratio(result.ideal_ratio(reading))}, {result.ideal_verdict(reading)} | "
                         f"{_sensitivity(result, reading)} | {_files(c.pair(reading))} |")
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
                lines.append(f"| {reading} | {_ratio(nominal)} ({verdict(nominal, c.paper_ratio)}) | " + " | ".join(
                    f"{_ratio(ratios.get((d.label, f)))} ({verdict(ratios.get((d.label, f)), c.paper_ratio)})"
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
    lines = ["| paper | claim | metric | paper ratio | ours, faithful: median [95%] (ideal) | verdict, x0.7/x1.4 | "
             "ours, mechanism: median [95%] (ideal) | verdict, x0.7/x1.4 |",
             "|---|---|---|---:|---:|---|---:|---|"]
    for paper, result in rows:
        c = result.claim
        cells = []
        for reading in ("faithful", "mechanism"):
            cells.append(f"{_with_interval(result, reading)} ({_ratio(result.ideal_ratio(reading))}) | "
                         f"**{result.verdict(reading)}**, {result.robustness(reading)[0]}")
        lines.append(f"| {paper} | [{c.id}](#{c.id.replace('_', '-')}) {c.claim} | {METRICS[c.metric]}"
                     f"{f' (t >= {c.from_time:g} s)' if c.from_time else ''} | {_paper_ratio(c.paper_ratio)} | "
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
    return write_atomically(Path(directory) / name, lambda tmp: tmp.write_text(text))


def main(argv=None) -> int:
    """python -m contouring_ros.studies.claims [FILE ...] [--maps]: evaluate claims files and print each claim's
    ratios and verdicts against what the file expects (for writing a claims file)."""
    import argparse
    parser = argparse.ArgumentParser(prog="python -m contouring_ros.studies.claims", description=main.__doc__)
    parser.add_argument("files", nargs="*", help="claims files (default: config/claims/paper*.yaml)")
    parser.add_argument("--maps", action="store_true", help="also compute and draw the regime maps into --out/maps")
    parser.add_argument("--out", default="reports")
    parser.add_argument("--draws", type=int, default=DRAWS, help=f"paired draws per pair (default {DRAWS})")
    parser.add_argument("--claim", action="append", help="only these claim ids (repeatable)")
    parser.add_argument("--yaml", action="store_true", help="also print the expected values in the file's form")
    args = parser.parse_args(argv)
    try:
        scores = ScenarioScores()
        for path in args.files or claim_files():
            paper = load_claims(path)
            if args.claim:
                import dataclasses
                paper = dataclasses.replace(paper, claims=tuple(c for c in paper.claims if c.id in args.claim),
                                            ccc_helps=())
            for result in evaluate(list(paper.claims), scores, draws=args.draws):
                c = result.claim
                print(f"{paper.paper}/{c.id} [{c.metric}{f' t>={c.from_time:g}' if c.from_time else ''}] paper "
                      f"{_paper_ratio(c.paper_ratio)}")
                for reading in ("faithful", "mechanism"):
                    if c.pair(reading) is None:
                        continue
                    median, low, high = result.interval(reading)
                    print(f"  {reading:9s} ratio {_with_interval(result, reading)} (expected "
                          f"{c.expected.get(f'{reading}_ratio')} {c.expected.get(f'{reading}_interval')}) verdict "
                          f"{result.verdict(reading)!r} (stated {c.verdict.get(reading)!r}); ideal "
                          f"{_ratio(result.ideal_ratio(reading))} (expected {c.expected.get(f'ideal_{reading}_ratio')})"
                          f" {result.ideal_verdict(reading)!r}; proposed {_um(result.value(reading, 0), c.metric)} um,"
                          f" baseline {_um(result.value(reading, 1), c.metric)} um")
                    print(f"    seed 0 {_ratio(result.nominal_ratio(reading))}; " + "; ".join(
                        f"{label} x{f:g} {_ratio(r)}" for (label, f), r in result.scaled_ratios(reading).items())
                        + f" -> {_sensitivity(result, reading)}")
                    if args.yaml:
                        print(f"    yaml: {reading}_ratio: {median:.4g}, {reading}_interval: [{low:.6g}, {high:.6g}], "
                              f"ideal_{reading}_ratio: {_ratio(result.ideal_ratio(reading))}; verdict "
                              f"{result.verdict(reading)}")
                if args.maps:
                    for i, spec in enumerate(c.maps):
                        print("  map:", draw_map(c, spec, map_ratios(c, spec, progress=sys.stderr.isatty()),
                                                 c.map_path(i, args.out)))
            for entry in paper.ccc_helps:
                with_ccc, without = ccc_helps_scores(entry, scores)
                print(f"{paper.paper} ccc_helps {entry.scenario} without {entry.without}: {with_ccc * 1e6:.4g} vs "
                      f"{without * 1e6:.4g} um ({METRICS[entry.metric]}), ratio {with_ccc / without:.3g}, stated "
                      f"factor {entry.factor:g}")
    except ConfigError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
