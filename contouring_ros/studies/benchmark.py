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
saturation and robustness constraints, a realistic machine, intervals over seeds and model mismatch). A run is
kept as a :class:`Part` (:mod:`.benchmark_parts`: saved, read back, merged with others) and written out by
:mod:`.benchmark_report` (the Markdown report and the CSV) and :mod:`.benchmark_figures` (heatmap, Pareto fronts).
"""
from __future__ import annotations

import fnmatch
import functools
import json
import math
from collections import Counter
from concurrent.futures import as_completed
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .checkpoints import Checkpoints
from .claims_file import claim_files, load_claims
from ..experiment.build import build_loop
from ..experiment.catalogue import CONTROLLERS, ESTIMATORS, SERVOS
from ..experiment.ros_yaml import read_yaml
from ..experiment.schema import GLOBAL_SECTION, REQUIRED
from ..core.simulation import simulate
from ..errors import ConfigError, Diverged
from .executors import pool as executor
from ..experiment.scenarios import CONFIG_DIR
from ..core.margins import LoopMargins
from ..core.metrics import Scores
from .parts import register as allow_in_parts
from .search import Agreement
from .shared_batches import SharedBatches
from .gains import gain_keys
from .machine import fit_to_machine, machine_settings
from .outcomes import experiment_for, run_outcomes, worst_case
from .summaries import interval
from .tuner import tune
from .tuning import Evaluation, Outcome, Protocol, Search, Tuned

__all__ = ["NOT_CONVERGED", "Family", "Combination", "Excluded", "Row", "Reference", "scenario_families",
           "select_families", "plan", "fit_to_machine", "lower_or_higher", "reference_job", "matches_methods",
           "is_proposed_combination", "proposed_row", "run_benchmark", "Part"]

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
        """The TACE verdict against the proposed combination (:func:`lower_or_higher` of the ratio's
        interval), or 'not converged' where this row's or the proposed row's searches did not agree: no ratio
        between two tunings is a result unless both are."""
        if not self.ok or self.reference is None:
            return ""
        if not (self.converged and self.reference.converged):
            return NOT_CONVERGED
        low, high = self.ratio("tace")[1:]
        return lower_or_higher(low, high)

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


def lower_or_higher(low: float, high: float, threshold: float = 1.0) -> str:
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


def _tune_rows_job(jobs: list, keep: str | None = None) -> list:
    """The :class:`Tuned` of each of ``jobs`` (rows of one scenario, each (the arguments of :func:`tune`: data,
    sections, keys, machine, noise limit, from_time, protocol, where; its robustness floor; its checkpoint
    key)), tuned side by side with their runs in one mixed batch a round
    (:class:`~contouring_ros.studies.shared_batches.SharedBatches`); each row's ``cpu`` its own work and its
    share of the rounds. ``keep``: the ``--checkpoints`` folder, where each row is kept as soon as it ends (a
    run stopped part way keeps the rows of a scenario that had ended)."""
    kept = Checkpoints(keep, Tuned) if keep else None

    def finished(i, tuned, cpu):
        tuned.cpu = cpu
        if kept is not None:
            kept.put(jobs[i][-1], tuned, jobs[i][7])

    shared = SharedBatches(finished)
    return shared.run([functools.partial(tune, *job[:8], robust_floor=job[8]) for job in jobs])


def _job_cost(rows: list) -> float:
    """What a scenario's job (its (row, job arguments)) is expected to cost, to start the longest first: the
    steps and axes of a run, once for each row and once more for each further pass of a learning controller."""
    data = rows[0][1][0]
    experiment = experiment_for(data, {}, {}, "benchmark")
    passes = sum(int(row.combination.sections["/ccc"].get("passes", 1) or 1) for row, _ in rows)
    return experiment.n_steps * len(experiment.axes) * (len(rows) + passes)


def matches_methods(label_of, methods) -> bool:
    """Whether a combination or excluded pairing (anything with estimator, controller and servo) is one of
    ``methods``: globs matched against its estimator, its controller and its servo set's label."""
    return any(fnmatch.fnmatch(name, pattern) for pattern in methods
               for name in (label_of.estimator, label_of.controller, label_of.servo))


def is_proposed_combination(family: Family, combination: Combination) -> bool:
    """Whether ``combination`` is the proposed file's own: its estimator, controller and servo sections."""
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
            combos = [c for c in combos if matches_methods(c, methods) or is_proposed_combination(family, c)]
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
        # one job per scenario, its rows tuned side by side; the longest first (a learning controller runs every
        # pass per evaluation), so that none starts last
        waiting = {}
        for row in jobs:
            family, combo, reference = row.family, row.combination, row.bound
            data = family.data[family.proposed]
            args = (data, fit_to_machine(data, combo.sections, reference.machine), combo.gain_keys,
                    reference.machine, reference.noise_limit, family.from_time, protocol)
            floor = reference.worst if math.isfinite(reference.worst) else 0.0
            key = checkpoints.key(*args, floor)
            row.tuned = checkpoints.get(key)
            if row.tuned is not None:
                row.status = row.tuned.status
                continue
            waiting.setdefault(family.name, []).append((row, (*args, f"{family.name} {combo.label}", floor, key)))
        if checkpoints.taken:
            say(f"{checkpoints.taken} of {len(jobs)} rows taken from {checkpoints.folder}")
        keep = str(checkpoints.folder) if checkpoints.folder is not None and not scheduler else None
        running = {}
        for name in sorted(waiting, key=lambda name: -_job_cost(waiting[name])):
            rows_here = waiting[name]
            running[pool.submit(_tune_rows_job, [job for _, job in rows_here], keep)] = rows_here
        with tqdm(total=len(jobs), initial=checkpoints.taken, desc="benchmark", disable=not progress,
                  leave=False) as bar:
            for job in as_completed(running):
                for (row, arguments), tuned in zip(running[job], job.result()):
                    row.tuned = tuned
                    row.status = tuned.status
                    checkpoints.put(arguments[-1], tuned, arguments[7])
                bar.update(len(running[job]))
    for family in families:
        mine = [r for r in rows if r.family is family and r.combination]
        proposed = proposed_row(family, mine)
        for row in mine:
            row.reference = proposed
    return rows


def proposed_row(family: Family, rows: list) -> Row | None:
    """The row of ``rows`` (each with a combination) that is ``family``'s proposed combination, if any."""
    return next((r for r in rows if is_proposed_combination(family, r.combination)), None)


# ---------------------------------------------------------------------------------------------- a run


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
