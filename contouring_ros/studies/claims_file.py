"""A paper's claims file: its format, read and checked into :class:`Claim` objects, and the verdict rules.

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

Scenario names are files of ``config/`` (:func:`scenario_experiment`, :func:`scenario_value` read them). A
ratio is proposed / baseline of the claim's metric (lower: the proposed method better). :func:`claim_verdict`
turns a ratio and the paper's into a verdict, :func:`interval_verdict` an interval of ratios, and
:func:`robustness` the verdicts with the decisive parameters scaled. The claims are measured by
:mod:`.claims`, their regime maps made by :mod:`.claims_maps`, and reported by :mod:`.claims_report`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import yaml

from ..experiment.files import load_experiment
from ..experiment.ros_yaml import read_yaml
from ..errors import ConfigError
from ..experiment.scenarios import CONFIG_DIR
from .sweep import experiments_for
from ..experiment.settings import grid_key_location

__all__ = ["VERDICTS", "METRICS", "VERDICT_RULE", "claim_verdict", "interval_verdict", "robustness", "Decisive",
           "Pair", "MapAxis", "RegimeMap", "Claim", "CCCHelps", "PaperClaims", "claim_files", "load_claims",
           "scenario_experiment", "scenario_value"]

VERDICTS = ("holds", "holds weaker", "does not hold", "reversed", "not testable", "undecided", "lowers",
            "does not lower")
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


def claim_verdict(ratio: float | None, paper_ratio: float | None) -> str:
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
    at_low, at_high = claim_verdict(low, paper_ratio), claim_verdict(high, paper_ratio)
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
    """A parameter that decides a claim: its grid keys, scaled alike (x :data:`.claims.SCALES`) in the pair's files."""

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


# ---------------------------------------------------------------------------------------------- scenarios


def scenario_experiment(name: str, settings: dict | None = None):
    """The experiment of the scenario file config/``name``.yaml, with the grid ``settings`` applied if any."""
    experiment = load_experiment(CONFIG_DIR / f"{name}.yaml")
    if not settings:
        return experiment
    return experiments_for(experiment.text, [settings], where=name)[0][1]


def scenario_value(name: str, key: str):
    """The value a grid key has in a scenario file (None where the file leaves it to a default)."""
    target, path = grid_key_location(read_yaml((CONFIG_DIR / f"{name}.yaml").read_text(), name), key)
    for part in path:
        if not isinstance(target, dict) or part not in target:
            return None
        target = target[part]
    return target
