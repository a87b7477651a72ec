"""The contouring benchmark: every estimator and controller of the registries on every paper scenario, each
tuned gain by gain under the same constraints on a realistic machine, scored alike with intervals, and the
best per scenario against the paper's proposed method.

Scenarios. The scenario files of config/ (``paper<N>_*.yaml``) that share the shared section (curve,
schedule, duration, initial state; the ``experiment`` and ``paper`` blocks aside) and every plant are one
scenario: its files differ only in the method (estimator, controller, servo). The scenario's *proposed* file
is the one a claim of config/claims/ names as proposed, else the file whose servo law, estimator and
controller are those of a proposed file of the same paper, else its first file. Its steady state starts at
the largest ``from_time`` of the claims on its files (else the paper's most common one). By default the
benchmark runs the scenarios of the papers' own experiments (:data:`DEFAULT_SCENARIOS`); the mechanism
scenarios (``*_mech_*``) of the claims are there on request.

Combinations. Every estimator x controller of the registries (plugins included) x every servo set the
scenario's files define (the servos are tuned to the scenario's plants; none is invented), each from the
scenario's own section of that type (estimators: else the first section of that type in any scenario file;
controllers: else a section of a controller with the same parameters, whose gains are in the same units).
A combination that validation refuses, that has no gains to start from, or that fails in its first steps
cannot be paired; the reason is kept. Three rules keep the pairings to those that can differ:
a controller that reads no estimate (its Entry's ``reads_estimate``: ``none``, the adaptive TNB, the MPCC) is
paired with the scenario's own estimator only (every other would give the same run); a learning controller
(its section runs ``passes`` > 1, each evaluation of its tuning running every pass) with the scenario's own
estimator and first servo set it can drive; a servo set whose law reads the reference ahead (a feedforward
such as the ZPETC) with ``none`` (the feedforward alone) and the proposed controller, on the scenario's own
estimator. Sections that model the drive (a ``command_delay`` key of a servo or controller, a controller's
``command_limit``) are given the realistic machine's delay and actuator limits (:func:`fit_to_machine`).

Tuning: :mod:`contouring_ros.studies.tuning` (every gain on its own, CMA-ES, equal budget, equal noise,
saturation and robustness constraints, a realistic machine, intervals over seeds and model mismatch).
"""
from __future__ import annotations

import csv
import fnmatch
import json
import math
import os
import time
from collections import Counter
from concurrent.futures import as_completed
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from .checkpoints import Checkpoints
from .claims import claim_files, load_claims
from ..experiment.build import build_loop
from ..experiment.catalogue import CONTROLLERS, ESTIMATORS, SERVOS
from ..experiment.ros_yaml import read_yaml
from ..experiment.schema import GLOBAL_SECTION, REQUIRED
from ..core.simulation import simulate
from ..errors import ConfigError, Diverged
from ..records.outputs import write_atomically
from .executors import pool as executor
from ..experiment.scenarios import CONFIG_DIR
from ..core.margins import LoopMargins
from ..core.metrics import Scores
from .parts import load as read_part, register as allow_in_parts, save as write_part
from .search import Agreement
from .gains import gain_keys
from .machine import REALISTIC, SATURATION_MARGIN, fit_to_machine, machine_settings
from .outcomes import experiment_for, run_outcomes, worst_case
from .summaries import interval, pareto_front
from .tuner import tune
from .tuning import Evaluation, Outcome, Protocol, Search, Tuned

__all__ = ["GOAL", "Family", "Combination", "Excluded", "Row", "Reference",
           "scenario_families", "select_families", "plan", "fit_to_machine", "reference_ranks", "Part", "save_part",
           "load_parts", "write_outputs", "reference_job", "run_benchmark", "write_csv", "draw_heatmap",
           "draw_pareto", "benchmark_report", "paper_best", "verdict"]

GOAL = 0.5              # a combination beats the proposed method 2x when both ratios' intervals are below this
NOT_CONVERGED = "not converged"     # the verdict where a row's (or the proposed row's) searches did not agree
MECHANISM = "_mech_"    # scenarios of the claims' mechanism files: run on request (--scenarios)
_META = ("experiment", "paper")


# ------------------------------------------------------------------------------------------- scenarios


@dataclass
class Family:
    """One scenario: the files of one paper that share the curve, schedule, timing and plants."""

    paper: str
    name: str
    files: list                   # scenario names, the proposed first
    proposed: str
    from_time: float
    data: dict = field(repr=False)    # scenario name -> its parsed file


def _read(path) -> dict:
    return read_yaml(Path(path).read_text(), str(path))


def _scenario_key(data: dict) -> str:
    shared = {k: v for k, v in data[GLOBAL_SECTION]["ros__parameters"].items() if k not in _META}
    plants = {node: body for node, body in data.items() if node.endswith("/plant")}
    return json.dumps([shared, plants], sort_keys=True, default=str)


def _signature(data: dict) -> tuple:
    axes = data[GLOBAL_SECTION]["ros__parameters"]["axes"]
    return (tuple(data[f"/{a}/servo"]["ros__parameters"]["law"] for a in axes),
            data["/contour_estimator"]["ros__parameters"]["type"], data["/ccc"]["ros__parameters"]["type"])


def _name(files: list, taken: set) -> str:
    tokens = [t for t in files[0].split("_") if all(t in f.split("_") for f in files)]
    name = "_".join(tokens) if len(tokens) > 1 else files[0]
    return name if name not in taken else files[0]


def scenario_families(config_dir=None, claims_dir=None) -> list:
    """Every scenario of the paper files in ``config_dir``, in paper and file order."""
    config_dir = Path(config_dir or CONFIG_DIR)
    paths = sorted(config_dir.glob("paper???_*.yaml"))
    data = {p.stem: _read(p) for p in paths}
    claims = [c for f in claim_files(claims_dir or config_dir / "claims") for c in load_claims(f).claims]
    faithful = {c.faithful.proposed for c in claims if c.faithful}
    mechanism = {c.mechanism.proposed for c in claims if c.mechanism}
    groups = {}
    for name, d in data.items():
        groups.setdefault((name[5:8], _scenario_key(d)), []).append(name)
    families, taken = [], set()
    for (paper, _), files in groups.items():
        chosen = None
        for proposed in (faithful, mechanism):
            signatures = {_signature(data[p]) for p in proposed if p in data and p[5:8] == paper}
            chosen = chosen or next((f for f in files if f in proposed), None) \
                or next((f for f in files if _signature(data[f]) in signatures), None)
        chosen = chosen or files[0]
        times = [c.from_time for c in claims for pair in (c.faithful, c.mechanism)
                 if pair and (pair.proposed in files or pair.baseline in files)]
        if not times:
            common = Counter(c.from_time for c in claims if c.paper == paper).most_common(1)
            times = [common[0][0]] if common else [0.0]
        files = [chosen] + [f for f in files if f != chosen]
        name = _name(files, taken)
        taken.add(name)
        families.append(Family(paper, name, files, chosen, max(times), {f: data[f] for f in files}))
    return families


def select_families(families: list, patterns: list | None) -> list:
    """The families whose name, or the name of one of whose files, matches one of ``patterns`` (globs); no
    patterns: the papers' own experiments (not the claims' mechanism scenarios)."""
    if not patterns:
        return [f for f in families if MECHANISM not in f.name]
    chosen = [f for f in families if any(fnmatch.fnmatch(n, p) for p in patterns for n in [f.name, *f.files])]
    if not chosen:
        raise ConfigError(f"--scenarios {' '.join(patterns)}: no scenario matches (scenarios: "
                          f"{', '.join(f.name for f in families)})")
    return chosen


# ---------------------------------------------------------------------------------------- combinations


@dataclass(frozen=True)
class Combination:
    estimator: str
    controller: str
    servo: str                    # the servo set's label
    sections: dict = field(hash=False, compare=False, repr=False)     # node -> its parameters
    gain_keys: tuple = ()

    @property
    def label(self) -> str:
        return f"{self.estimator} + {self.controller} / {self.servo}"


@dataclass(frozen=True)
class Excluded:
    estimator: str
    controller: str
    servo: str
    reason: str

    @property
    def label(self) -> str:
        return f"{self.estimator} + {self.controller} / {self.servo}"


def _params(data: dict, node: str) -> dict:
    return data.get(node, {}).get("ros__parameters", {})


def _servo_sets(family: Family) -> dict:
    """label -> {'/<axis>/servo': parameters} for each distinct servo set of the scenario's files."""
    base = family.data[family.proposed]
    axes = base[GLOBAL_SECTION]["ros__parameters"]["axes"]
    sets = []
    for name in family.files:
        servos = {f"/{a}/servo": _params(family.data[name], f"/{a}/servo") for a in axes}
        if servos not in sets:
            sets.append(servos)
    out = {}
    for servos in sets:
        first = servos[f"/{axes[0]}/servo"]
        label = first["law"]
        same = [s for s in sets if s[f"/{axes[0]}/servo"]["law"] == label]
        if len(same) > 1 and servos is not same[0]:
            ref = same[0][f"/{axes[0]}/servo"]
            diff = [f"{k}={first.get(k)}" for k in sorted(set(first) | set(ref)) if first.get(k) != ref.get(k)]
            label = f"{label} ({', '.join(diff) or f'set {same.index(servos) + 1}'})"
        out[label] = servos
    return out


def _controller_seed(family: Family, controller: str):
    """(the sections the controller's gains may be scaled from, the proposed file's first; None) or (None, why
    there are none). Each combination takes the first of them that it validates with (e.g. a task-frame
    controller's approximation must match the estimator)."""
    params = CONTROLLERS.entry(controller).params
    sections = [_params(family.data[f], "/ccc") for f in family.files]
    own = []
    for s in sections:
        if s.get("type") == controller and s not in own:
            own.append(dict(s))
    if own:
        return own, None
    if all(p.default is not REQUIRED for p in params.values()):
        return [{"type": controller}], None
    for s in sections:
        other = CONTROLLERS.entry(s["type"]).params if s.get("type") in CONTROLLERS else {}
        if params and set(other) == set(params):
            return [{**s, "type": controller}], None
    return None, (f"no {controller} gains to start from: the scenario's files define no {controller} section "
                  f"nor a controller with the same parameters")


def _estimator_section(family: Family, estimator: str, catalogue: dict) -> dict:
    for f in family.files:
        section = _params(family.data[f], "/contour_estimator")
        if section.get("type") == estimator:
            return dict(section)
    return dict(catalogue.get(estimator, {"type": estimator}))


def _catalogue_estimators(families: list) -> dict:
    out = {}
    for family in families:
        for d in family.data.values():
            section = _params(d, "/contour_estimator")
            out.setdefault(section.get("type"), dict(section))
    return out


def _experiment(family: Family, sections: dict, where: str, settings: dict | None = None):
    return experiment_for(family.data[family.proposed], sections, settings or {}, where)


def _probe(family: Family, sections: dict) -> str:
    """'' when the combination runs its first steps, else why not (an error other than divergence)."""
    base = family.data[family.proposed][GLOBAL_SECTION]["ros__parameters"]
    try:
        experiment = _experiment(family, sections, family.name, {"duration": 5 * float(base["sample_time"])})
    except ConfigError as error:
        return str(error).split(": ", 1)[-1]
    try:
        with np.errstate(all="ignore"):
            simulate(build_loop(experiment))
    except Diverged:
        return ""
    except Exception as error:      # noqa: BLE001 - any failure of a pairing is its reason
        return f"fails in its first steps: {type(error).__name__}: {' '.join(str(error).split())[:200]}"
    return ""


def plan(family: Family, catalogue: dict | None = None) -> tuple:
    """(combinations, excluded) of a scenario: every estimator x controller x servo set (see the module
    docstring), the ones that cannot be paired with the reason. ``catalogue``: estimator type -> the section
    an estimator the scenario does not use starts from (default: the first of each type in config/)."""
    catalogue = catalogue if catalogue is not None else _catalogue_estimators(scenario_families())
    servo_sets = _servo_sets(family)
    direct = {label: all(SERVOS.entry(s["law"]).direct for s in servos.values())
              for label, servos in servo_sets.items()}
    own_estimator = _params(family.data[family.proposed], "/contour_estimator")["type"]
    own_controller = _params(family.data[family.proposed], "/ccc")["type"]
    feedforward = {label for label, servos in servo_sets.items()
                   if any(SERVOS.entry(s["law"]).preview is not None for s in servos.values())}
    combos, excluded = [], []
    for controller in CONTROLLERS.names():
        entry = CONTROLLERS.entry(controller)
        estimators = ESTIMATORS.names() if entry.reads_estimate else [own_estimator]
        usable = {label for label in servo_sets if direct[label] == entry.whole_command
                  and (label not in feedforward or controller in ("none", own_controller))}
        if not usable:
            why = (f"computes every axis' whole command and needs 'direct' servos; the scenario's files drive "
                   f"its plants only through {', '.join(sorted(servo_sets))}") if entry.whole_command else \
                  (f"adds a correction to a servo's command; the scenario's files define only "
                   f"{', '.join(sorted(servo_sets))}, which pass the controller's output through")
            excluded += [Excluded(e, controller, "any", why) for e in estimators]
            continue
        seed, why = _controller_seed(family, controller)
        if seed is None:
            excluded += [Excluded(e, controller, "any", why) for e in estimators]
            continue
        learning = any(int(section.get("passes", 1) or 1) > 1 for section in seed)
        if learning:
            estimators = [own_estimator]
            usable = {next(label for label in servo_sets if label in usable)}
        for estimator in estimators:
            for label in servo_sets:
                if label not in usable:
                    continue
                if label in feedforward and estimator != own_estimator:
                    continue
                problems = []
                for section in seed:
                    sections = {"/contour_estimator": _estimator_section(family, estimator, catalogue),
                                "/ccc": section, **servo_sets[label]}
                    problems.append(_probe(family, sections))
                    if not problems[-1]:
                        combos.append(Combination(estimator, controller, label, sections,
                                                  gain_keys(controller, section)))
                        break
                else:
                    excluded.append(Excluded(estimator, controller, label, problems[0]))
    return combos, excluded


# ---------------------------------------------------------------------------------------------- tuning


@dataclass
class Reference:
    """What every combination of a scenario is held to: the machine and the proposed method's noise
    sensitivity with the paper's gains on it."""

    machine: dict                 # grid settings of the scenario's realistic machine
    published: object             # tuning.Outcome: the proposed file's gains on that machine
    ideal_published: object       # ... on the ideal machine (the file as it is)
    noise_limit: float            # the noise sensitivity every combination must stay under
    worst: float = math.nan       # the proposed method's worst TACE [m] at +-perturbation (outcomes.worst_case)


@dataclass
class Row:
    family: Family
    combination: Combination | None
    excluded: Excluded | None = None
    tuned: object = None          # tuning.Tuned
    status: str = ""
    reference: "Row | None" = None         # the proposed combination's row of the scenario (tuned)
    bound: Reference | None = None

    @property
    def label(self) -> str:
        return (self.combination or self.excluded).label

    @property
    def is_proposed(self) -> bool:
        return self.reference is self

    @property
    def ok(self) -> bool:
        return self.tuned is not None and self.tuned.nominal is not None

    @property
    def gains(self) -> dict:
        return self.tuned.gains if self.ok else {}

    def figure(self, metric: str) -> tuple:
        """(median, 2.5%, 97.5%) of ``metric`` (tace, mce, rms) over the draws, in metres."""
        if not self.ok:
            return math.nan, math.nan, math.nan
        return interval([getattr(d, metric) for d in self.tuned.draws])

    def ratios(self, metric: str) -> list:
        """This row's ``metric`` over the proposed combination's, draw by draw (the same draws)."""
        if not self.ok or self.reference is None or not self.reference.ok:
            return []
        return [mine / theirs if mine == mine and theirs > 0 else math.inf
                for mine, theirs in zip((getattr(d, metric) if d.ok else math.inf for d in self.tuned.draws),
                                        (getattr(d, metric) if d.ok else math.nan for d in self.reference.tuned.draws))]

    def ratio(self, metric: str) -> tuple:
        """(median, 2.5%, 97.5%) of :meth:`ratios`; a draw that diverged counts as infinitely worse."""
        values = self.ratios(metric)
        if not values:
            return math.nan, math.nan, math.nan
        values = np.asarray(values, dtype=float)
        values = values[~np.isnan(values)]
        if not values.size:
            return math.nan, math.nan, math.nan
        return _infinite_aware(values, 50.0), _infinite_aware(values, 2.5), _infinite_aware(values, 97.5)

    @property
    def converged(self) -> bool:
        """Whether the row's searches agreed (tuning.Tuned.converged); a row with nothing to tune is."""
        return self.tuned is not None and self.tuned.converged

    def tace_verdict(self) -> str:
        """The TACE verdict against the proposed combination (:func:`verdict` of the ratio's interval), or
        'not converged' where this row's or the proposed row's searches did not agree: no ratio between two
        tunings is a result unless both are."""
        if not self.ok or self.reference is None:
            return ""
        if not (self.converged and self.reference.converged):
            return NOT_CONVERGED
        low, high = self.ratio("tace")[1:]
        return verdict(low, high)

    @property
    def noise_ratio(self) -> float:
        """Noise sensitivity (tuned, nominal) over the proposed method's with the paper's gains."""
        if not self.ok or self.bound is None or not self.bound.published.ok or self.bound.published.noise <= 0:
            return math.nan
        return self.tuned.nominal.noise / self.bound.published.noise


def _infinite_aware(values: np.ndarray, q: float) -> float:
    """The q-th percentile of ``values`` where inf (a diverged draw) is larger than any number: numpy's linear
    interpolation gives nan between two infs; here it gives inf, as it does between a number and inf."""
    huge = np.finfo(float).max / 4
    found = float(np.percentile(np.where(np.isinf(values), np.sign(values) * huge, values), q))
    return math.copysign(math.inf, found) if abs(found) >= huge / 2 else found


def verdict(low: float, high: float, threshold: float = 1.0) -> str:
    """'lower' when the interval lies below ``threshold``, 'higher' above it, 'same' when it is the
    threshold itself to 1e-9 (a method that does not read what differs), else 'undecided'."""
    if not (math.isfinite(low) or math.isfinite(high)) or low != low or high != high:
        return "undecided"
    if abs(low - threshold) <= 1e-9 * threshold and abs(high - threshold) <= 1e-9 * threshold:
        return "same"
    if high < threshold:
        return "lower"
    if low > threshold:
        return "higher"
    return "undecided"


def reference_job(data: dict, from_time: float, where: str, protocol: Protocol | None = None) -> Reference:
    """The :class:`Reference` of a scenario (its experiment ``data``): its realistic machine, the proposed
    method's outcome on it and on the ideal machine, and its worst case under ``protocol``'s perturbations
    (``noise_limit`` is nan here: the caller sets it from ``protocol``)."""
    ideal = run_outcomes(data, {}, [{}], from_time, where)[0]
    machine = machine_settings(data, "realistic", ideal.peak_command if ideal.ok else ())
    published = run_outcomes(data, {}, [machine], from_time, where)[0]
    return Reference(machine, published, ideal, math.nan,
                     worst_case(data, {}, machine, from_time, protocol or Protocol(), where))


def _tune_job(data, sections, keys, machine, noise_limit, from_time, protocol, where, robust_floor):
    started = time.thread_time()           # this worker thread's CPU: right on processes and Dask threads alike
    tuned = tune(data, sections, keys, machine, noise_limit, from_time, protocol, where, robust_floor=robust_floor)
    tuned.cpu = time.thread_time() - started
    return tuned


def matches_methods(label_of, methods) -> bool:
    """Whether a combination or excluded pairing (anything with estimator, controller and servo) is one of
    ``methods``: globs matched against its estimator, its controller and its servo set's label."""
    return any(fnmatch.fnmatch(name, pattern) for pattern in methods
               for name in (label_of.estimator, label_of.controller, label_of.servo))


def _is_proposed(family: Family, combination: Combination) -> bool:
    data = family.data[family.proposed]
    axes = data[GLOBAL_SECTION]["ros__parameters"]["axes"]
    return (combination.estimator == _params(data, "/contour_estimator")["type"]
            and combination.controller == _params(data, "/ccc")["type"]
            and all(combination.sections[f"/{a}/servo"] == _params(data, f"/{a}/servo") for a in axes))


def run_benchmark(families: list, protocol: Protocol | None = None, workers: int | None = None,
                  progress: bool = False, say=None, scheduler: str | None = None, methods=(),
                  checkpoints: Checkpoints | None = None) -> list:
    """Every row (one per scenario x combination, the excluded ones included) of ``families``, on local
    processes or the Dask cluster at ``scheduler`` (:func:`contouring_ros.studies.executors.pool`). ``methods``
    (globs, :func:`matches_methods`): only those combinations, and each scenario's proposed one (the ratios
    are to it). With ``checkpoints``, a row kept there from an earlier run of the same inputs and code is
    taken as it is, and each row tuned now is kept there as it finishes."""
    from tqdm import tqdm
    protocol = protocol or Protocol()
    checkpoints = checkpoints or Checkpoints(None, Tuned)
    say = say or (lambda message: None)
    catalogue = _catalogue_estimators(scenario_families() if families else [])
    plans, matched = {}, 0
    for family in families:
        combos, excluded = plan(family, catalogue)
        if methods:
            matched += sum(matches_methods(c, methods) for c in combos + excluded)
            combos = [c for c in combos if matches_methods(c, methods) or _is_proposed(family, c)]
            excluded = [e for e in excluded if matches_methods(e, methods)]
        plans[family.name] = combos, excluded
    if methods and not matched:
        raise ConfigError(f"--methods {' '.join(methods)}: no estimator, controller or servo set of the chosen "
                          "scenarios matches")
    rows = []
    with executor(workers, scheduler, tasks=max(len(families), sum(len(c) for c, _ in plans.values()))) as (pool, _):
        references = {f.name: pool.submit(reference_job, f.data[f.proposed], f.from_time, f.name, protocol) for f in families}
        jobs = []
        for family in families:
            combos, excluded = plans[family.name]
            say(f"{family.name}: {len(combos)} combinations, {len(excluded)} cannot be paired")
            reference = references[family.name].result()
            reference.noise_limit = protocol.noise_factor * reference.published.noise \
                if reference.published.ok else math.inf
            for combo in combos:
                row = Row(family, combo, bound=reference)
                rows.append(row)
                jobs.append(row)
            rows += [Row(family, None, e, status=f"cannot be paired: {e.reason}") for e in excluded]
        # the longest first (a learning controller runs every pass per evaluation), so that none starts last
        running = {}
        with tqdm(total=len(jobs), desc="benchmark", disable=not progress, leave=False) as bar:
            for row in sorted(jobs, key=lambda r: -int(r.combination.sections["/ccc"].get("passes", 1) or 1)):
                family, combo, reference = row.family, row.combination, row.bound
                data = family.data[family.proposed]
                args = (data, fit_to_machine(data, combo.sections, reference.machine), combo.gain_keys,
                        reference.machine, reference.noise_limit, family.from_time, protocol)
                floor = reference.worst if math.isfinite(reference.worst) else 0.0
                key = checkpoints.key(*args, floor)
                row.tuned = checkpoints.get(key)
                if row.tuned is not None:
                    row.status = row.tuned.status
                    bar.update(1)
                    continue
                running[pool.submit(_tune_job, *args, f"{family.name} {combo.label}", floor)] = row, key
            if checkpoints.taken:
                say(f"{checkpoints.taken} of {len(jobs)} rows taken from {checkpoints.folder}")
            for job in as_completed(running):
                row, key = running[job]
                row.tuned = job.result()
                row.status = row.tuned.status
                checkpoints.put(key, row.tuned, f"{row.family.name} {row.combination.label}")
                bar.update(1)
    for family in families:
        mine = [r for r in rows if r.family is family and r.combination]
        proposed = _proposed_row(family, mine)
        for row in mine:
            row.reference = proposed
    return rows


def _proposed_row(family: Family, rows: list) -> Row | None:
    return next((r for r in rows if _is_proposed(family, r.combination)), None)


# ---------------------------------------------------------------------------------------------- output


def _um(value) -> str:
    return "" if value is None or not math.isfinite(value) else f"{value * 1e6:.6g}"


def _num(value) -> str:
    return "" if value is None or not math.isfinite(value) else f"{value:.6g}"


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
                    *((a.searches, a.agreed, _num(a.spread), "yes" if a.converged else "no")
                      if (a := t and t.agreement) else ("",) * 4),
                    t.robustness_runs if t else "", _num(t.robust_worst) if t else "",
                    _um(n.tace if n else None), _um(n.mce if n else None), _num(n.noise if n else None),
                    _num(row.noise_ratio), _num(n.saturated if n else None), _num(n.effort if n else None),
                    *(_um(v) for v in tace), *(_um(v) for v in mce), *(_num(v) for v in tr), *(_num(v) for v in mr),
                    "" if row.is_proposed else row.tace_verdict(),
                    _um(t.ideal.tace if t and t.ideal else None), _um(t.ideal.mce if t and t.ideal else None),
                    *((_num(m.ms), _num(m.gain_margin), _num(m.phase_margin_deg)) if (m := t and t.margins) else ("",) * 3)])
    write_atomically(path, write)
    return path


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
                    mark = "" if row.is_proposed or verdict(low, high) != "undecided" else "~"
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


def _f(value, digits=3) -> str:
    return "-" if value is None or value != value else f"{value:.{digits}g}"


def _iv(triple, scale: float = 1.0, digits: int = 3) -> str:
    median, low, high = (v * scale if v == v else v for v in triple)
    if median != median:
        return "-"
    return f"{_f(median, digits)} [{_f(low, digits)}, {_f(high, digits)}]"


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
        here = (f"| {family.name} | {proposed.label} | {_f(proposed.figure('tace')[0] * 1e6)} / "
                f"{_f(proposed.figure('mce')[0] * 1e6)} ")
        if best is None:
            lines.append(here + "| no other combination | | | | | |")
            continue
        tr = best.ratio("tace")
        lines.append(here + f"| {best.label} | {_f(best.figure('tace')[0] * 1e6)} / {_f(best.figure('mce')[0] * 1e6)} "
                     f"| {_iv(tr)} | {_iv(best.ratio('mce'))} | {best.tace_verdict()} | "
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
                         f"{_iv(r.figure('tace'), 1e6)} | {_iv(r.figure('mce'), 1e6)} | {_iv(tr)} | "
                         f"{_iv(r.ratio('mce'))} | {r.tace_verdict() or '-'} | {r.status} |")
    return lines


def _gain_text(row: Row) -> str:
    if not row.ok or not row.gains:
        return "-"
    point = getattr(row.tuned, "point", {}) or {}
    text = ", ".join(f"{k} {'off' if v == 0 else _f(v)}" for k, v in point.items())
    raw = ", ".join(f"{k} {_f(v)}" for k, v in row.gains.items())
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
    return f"{m.ms:.2f} ({_f(m.gain_margin, 2)}, {m.phase_margin_deg:.0f} deg{unstable})"


def _family_table(rows: list, family: Family) -> list:
    mine = [r for r in rows if r.family is family and r.combination]
    ranked = sorted(mine, key=lambda r: (not r.ok, r.figure("tace")[0] if r.ok else 0.0))
    ref = mine[0].bound if mine else None
    published = ref.published if ref else None
    head = [f"Steady state from t = {family.from_time:g} s; proposed file `{family.proposed}`, {len(mine)} "
            "combinations. The proposed method with the paper's gains on this machine: "
            + (f"TACE {_f(published.tace * 1e6)} um, MCE {_f(published.mce * 1e6)} um (ideal machine: "
               f"{_f(ref.ideal_published.tace * 1e6)} / {_f(ref.ideal_published.mce * 1e6)} um)."
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
                    f"{_iv(r.figure('tace'), 1e6)} | {_iv(r.figure('mce'), 1e6)} | {'1' if r.is_proposed else _iv(tr)} | "
                    f"{'' if r.is_proposed else r.tace_verdict()}{status} | {_f(r.noise_ratio)} | "
                    f"{_f(100 * t.nominal.saturated, 2)}% | {_f(t.robust_worst)}x | {_margin_text(t.margins)} | "
                    f"{_f(ideal.tace * 1e6) if ideal and ideal.ok else 'diverged'} / "
                    f"{_f(ideal.mce * 1e6) if ideal and ideal.ok else '-'} |")
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
    text = (f" **Convergence**: {len(converged)} of {len(tuned)} tuned rows converged "
            f"({100 * len(converged) / len(tuned):.0f}%); searches per row: median {float(np.median(searches)):g}, "
            f"at most {max(searches)}.")
    left = [r for r in tuned if not r.converged]
    if left:
        text += " Not converged (no verdict rests on them): " + "; ".join(
            f"{r.family.name} {r.label} ({r.tuned.agreement.agreed} of {r.tuned.agreement.searches} agree, "
            f"spread {_f(r.tuned.agreement.spread)}x)" for r in left) + "."
    return text


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
    runs = sum(len(r.tuned.evaluations) + r.tuned.robustness_runs + len(r.tuned.draws) + 1
               for r in compatible if r.tuned)
    tuned = [r for r in compatible if r.ok and r.tuned.space]
    at_bound = [r for r in tuned if r.tuned.at_bound]
    upper = [r for r in tuned if any("upper" in b for b in r.tuned.at_bound)]
    not_robust = [r for r in compatible if r.tuned and r.status.startswith("not robust")]
    none = [r for r in compatible if not r.ok]
    machine = ", ".join(f"{k} {v}" for k, v in REALISTIC.items())
    lines = [
        "# Contouring benchmark: every estimator and controller on every scenario, each gain tuned under equal "
        "constraints on a realistic machine", "",
        f"{where}; in-process simulation): {len(families)} scenarios "
        f"of {len({f.paper for f in families})} papers, {len(compatible)} combinations ({runs} runs), "
        f"{len(rows) - len(compatible)} pairings that cannot be made. Every figure in micrometres is the exact "
        "contour error (distance to the whole curve) in the scenario's steady state; ratios are to the scenario's "
        "proposed method tuned the same way, draw by draw. All rows: [benchmark.csv](benchmark.csv).", "",
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
        "and the Ms their loops reach (1.2 to the bound), the gain scale solved for that Ms; the ZPETC's PID "
        "likewise, at a chosen Ms of each axis' own loop (each axis' largest stable gain scale at that Ms; a "
        "contour controller beside it then in crossover frequencies, its coupled loop held to the bound); the "
        "other PID contour controllers: the proportional and integral terms' crossover frequencies "
        "through the axes' plant (f_p, f_i, each 0.1 Hz to an eighth of the sample rate, or off) and the "
        "derivative's ratio to the proportional term at f_p (r_d); task_frame_pd: its bandwidths and damping ratio; tvt: its bandwidth; "
        "adaptive_tnb: its tracking bandwidth and its coupling and adaptation gains as ratios to the paper's; "
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
        "A row marked *not robust* had no robust point: its point with the lowest worst case is shown, and "
        "it cannot be the best of its scenario.",
        f"- **Intervals**: each tuned method runs {protocol.draws} draws (noise seed, model mismatch within "
        f"+-{100 * protocol.mismatch:g}% of every plant parameter), the same draws for every method of a "
        "scenario; figures are the median [2.5%, 97.5%] over the draws, ratios are taken draw by draw. A "
        "verdict is *lower* or *higher* only where the whole interval is on one side of 1, else *undecided*; "
        f"the 2x goal needs both ratios' intervals at or below {GOAL:g}.",
        f"- **Where the search ended**: {len(at_bound)} of {len(tuned)} tuned combinations have a coordinate at "
        f"an end of its range ({len(upper)} at an upper bound, where a larger value might do better; the others "
        f"with a term switched off or at a lower bound). {len(not_robust)} not robust; {len(none)} without an admissible "
        "point." + convergence_text(tuned), ""] + (
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


@dataclass
class Part:
    """One run of the benchmark over some scenarios, kept to be reported with others (``--save-part``,
    ``--from-parts``): a cluster or a large machine can run the papers apart."""

    families: list
    rows: list
    protocol: Protocol
    seconds: float                # wall time
    cpu: float                    # CPU time of the process and its workers
    cores: int
    command: str
    host: str = ""
    load: float = math.nan        # load average as it ended
    methods: tuple = ()           # --methods: only these combinations (and each scenario's proposed one) ran
    resumed: int = 0              # rows taken from --checkpoints of an earlier run (their CPU is not in cpu)


allow_in_parts(Part, Family, Combination, Excluded, Reference, Row, Protocol, Outcome, Evaluation, Tuned, Search,
               Agreement, LoopMargins, Scores)


def save_part(part: Part, path) -> Path:
    """Write ``part`` to ``path`` as a part file (:mod:`contouring_ros.studies.parts`: JSON with a format version and
    a checksum, read back by :func:`load_parts`; nothing in it can run code)."""
    return write_part(part, path)


def load_parts(paths: list) -> list:
    """The :class:`Part` of each file in ``paths`` (:func:`contouring_ros.studies.parts.load`: checked before anything
    is built). ConfigError naming a file that is not one, whose rows do not hang together, or whose protocol
    differs from the first's (their rows would not compare)."""
    parts = []
    for path in paths:
        part = read_part(path, f"--from-parts {path}")
        if not isinstance(part, Part):
            raise ConfigError(f"--from-parts {path}: not a benchmark part (it holds a {type(part).__name__})")
        problem = next((what for ok, what in (
            (all(isinstance(f, Family) for f in part.families), "a scenario that is not a Family"),
            (all(isinstance(r, Row) for r in part.rows), "a row that is not a Row"),
            (all(any(r.family is f for f in part.families) for r in part.rows), "a row of no scenario of the part"),
            (all((r.combination is None) != (r.excluded is None) for r in part.rows),
             "a row with neither or both of a combination and an exclusion"),
            (all(r.tuned is None or isinstance(r.tuned, Tuned) for r in part.rows), "a row whose tuning is not Tuned"),
        ) if not ok), None)
        if problem:
            raise ConfigError(f"--from-parts {path}: odd contents for a benchmark part: {problem}")
        if parts and part.protocol != parts[0].protocol:
            raise ConfigError(f"--from-parts {path}: its tuning protocol differs from {paths[0]}'s")
        parts.append(part)
    return parts


def _same_tuning(before: Row, after: Row) -> bool:
    """Whether two runs of one combination gave the same figures (every draw's TACE and MCE, and the proposed
    method's with the paper's gains; a diverged draw's nan equal to nan)."""
    def figures(row):
        draws = row.tuned.draws if row.ok else []
        published = row.bound.published if row.bound is not None else None
        return np.array([[d.tace, d.mce] for d in draws] + ([[published.tace, published.mce]] if published else []),
                        dtype=float)
    mine, theirs = figures(before), figures(after)
    return before.ok == after.ok and mine.shape == theirs.shape and bool(np.allclose(mine, theirs, rtol=1e-9,
                                                                                     atol=0.0, equal_nan=True))


def merged_rows(parts: list) -> tuple:
    """(families, rows) of ``parts`` read in order: a later part's scenario replaces an earlier part's rows
    of it, all of them, or with ``methods`` those of its methods and the proposed combination (so that a
    method added or changed is rerun alone and reported with the rest). ConfigError where the proposed
    combination of a scenario did not tune to the same figures in both (the parts ran different code or
    settings: their ratios would not compare)."""
    families, rows = {}, {}
    for i, part in enumerate(parts):
        for family in part.families:
            new = [r for r in part.rows if r.family is family]
            kept = [] if not part.methods or family.name not in rows else [
                r for r in rows[family.name]
                if not matches_methods(r.combination or r.excluded, part.methods)
                and not (r.combination and _is_proposed(family, r.combination))]
            before = next((r for r in rows.get(family.name, []) if r.combination
                           and _is_proposed(family, r.combination)), None)
            after = next((r for r in new if r.combination and _is_proposed(family, r.combination)), None)
            if part.methods and before is not None and after is not None and not _same_tuning(before, after):
                raise ConfigError(f"--from-parts: part {i + 1} ({part.command}) tuned {family.name}'s proposed "
                                  "combination to other figures than the parts before it: they ran different "
                                  "code or settings, so its rows would not compare with theirs")
            for r in kept:
                r.family = family
                if after is not None:
                    r.bound = after.bound
            families[family.name] = family
            rows[family.name] = kept + new
    ordered = sorted(families.values(), key=lambda f: f.paper)
    out = []
    for family in ordered:
        mine = rows[family.name]
        proposed = _proposed_row(family, [r for r in mine if r.combination])
        for r in mine:
            if r.combination:
                r.reference = proposed
        out += mine
    return ordered, out


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
