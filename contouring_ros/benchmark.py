"""The contouring benchmark: every estimator and controller of the registries on every paper scenario, tuned
by one rule, scored alike, and the best per scenario against the paper's proposed method.

Scenarios. The scenario files of config/ (``paper<N>_*.yaml``) that share the shared section (curve,
schedule, duration, initial state; the ``experiment`` and ``paper`` blocks aside) and every plant are one
scenario: its files differ only in the method (estimator, controller, servo). The scenario's *proposed* file
is the one a claim of config/claims/ names as proposed, else the file whose servo law, estimator and
controller are those of a proposed file of the same paper, else its first file. Its steady state starts at
the largest ``from_time`` of the claims on its files (else the paper's most common one).

Combinations. Every estimator x controller of the registries (plugins included) x every servo set the
scenario's files define (the servos are tuned to the scenario's plants; none is invented), each from the
scenario's own section of that type (estimators: else the first section of that type in any scenario file;
controllers: else a section of a controller with the same parameters, whose gains are in the same units).
A combination that validation refuses, that has no gains to start from, or that fails in its first steps
cannot be paired; the reason is kept. The controller ``none`` reads no estimate: it is paired with the
scenario's own estimator only.

Tuning rule (the same for every combination). The controller's gains (:data:`GAIN_KEYS`; every one scaled
by one factor, so a PID keeps its zeros and a task-frame controller its damping ratios) take ``budget``
factors on a log grid from 1/:data:`SPAN` to :data:`SPAN` (and 1, the file's own gains); the runs that did
not diverge and whose RMS actuator effort is at most :data:`EFFORT_BOUND` times that of the proposed
method with the file's gains are admissible, and the admissible run with the lowest steady-state TACE is
the combination's result.
"""
from __future__ import annotations

import copy
import csv
import fnmatch
import json
import math
import os
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

__all__ = ["EFFORT_BOUND", "SPAN", "DEFAULT_BUDGET", "GAIN_KEYS", "Family", "Combination", "Excluded", "Point",
           "Row", "scenario_families", "select_families", "factors", "plan", "select", "run_benchmark",
           "write_csv", "draw_heatmap", "benchmark_report", "paper_best"]

EFFORT_BOUND = 1.1      # admissible: RMS effort <= this times the proposed method's (file gains)
SPAN = 100.0            # gain factors from 1/SPAN to SPAN
EQUAL_EFFORT = 1.01     # best versus proposed: RMS effort at most this times the proposed's ("equal or lower")
DEFAULT_BUDGET = 5      # grid points per combination (odd: the file's own gains are one of them)
GOAL = 0.5              # a combination beats the proposed method 2x when both ratios are at most this
BATCH = 120             # runs per vectorised batch
# the gains the tuning rule scales, per controller type; a controller not listed: its float parameters
# whose names start with 'k' (kp, kc ...)
GAIN_KEYS = {"variable_gain": ("kp", "ki", "kd"), "unit_vector": ("kp", "ki", "kd"), "tvt": ("kc",),
             "task_frame_pd": ("f_t", "f_n", "f_b"), "adaptive_tnb": ("coupling",), "none": ()}
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
    from .config import read_yaml
    return read_yaml(Path(path).read_text(), str(path))


def _scenario_key(data: dict) -> str:
    shared = {k: v for k, v in data["/**"]["ros__parameters"].items() if k not in _META}
    plants = {node: body for node, body in data.items() if node.endswith("/plant")}
    return json.dumps([shared, plants], sort_keys=True, default=str)


def _signature(data: dict) -> tuple:
    axes = data["/**"]["ros__parameters"]["axes"]
    return (tuple(data[f"/{a}/servo"]["ros__parameters"]["law"] for a in axes),
            data["/contour_estimator"]["ros__parameters"]["type"], data["/ccc"]["ros__parameters"]["type"])


def _name(files: list, taken: set) -> str:
    tokens = [t for t in files[0].split("_") if all(t in f.split("_") for f in files)]
    name = "_".join(tokens) if len(tokens) > 1 else files[0]
    return name if name not in taken else files[0]


def scenario_families(config_dir=None, claims_dir=None) -> list:
    """Every scenario of the paper files in ``config_dir``, in paper and file order."""
    from .claims import claim_files, load_claims
    from .paper import CONFIG_DIR
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
    """The families whose name, or the name of one of whose files, matches one of ``patterns`` (globs)."""
    if not patterns:
        return families
    from .errors import ConfigError
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


def factors(budget: int) -> list:
    """``budget`` factors on a log grid from 1/SPAN to SPAN, with 1 (the file's gains) among them."""
    budget = max(1, int(budget))
    grid = [1.0] if budget == 1 else [float(SPAN ** (2 * i / (budget - 1) - 1)) for i in range(budget)]
    if not any(math.isclose(f, 1.0) for f in grid):
        grid.append(1.0)
    return sorted(grid)


def _gain_keys(controller: str, section: dict) -> tuple:
    from .config import CONTROLLERS
    if controller in GAIN_KEYS:
        keys = GAIN_KEYS[controller]
    else:
        params = CONTROLLERS.entry(controller).params
        keys = tuple(k for k, p in params.items() if p.kind in ("float", "floats") and k.startswith("k"))
    return tuple(k for k in keys if section.get(k) is not None)


def _scaled(section: dict, keys: tuple, factor: float) -> dict:
    out = dict(section)
    for key in keys:
        value = out[key]
        out[key] = [float(v) * factor for v in value] if isinstance(value, list) else float(value) * factor
    return out


def _params(data: dict, node: str) -> dict:
    return data.get(node, {}).get("ros__parameters", {})


def _servo_sets(family: Family) -> dict:
    """label -> {'/<axis>/servo': parameters} for each distinct servo set of the scenario's files."""
    base = family.data[family.proposed]
    axes = base["/**"]["ros__parameters"]["axes"]
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
    from .config import CONTROLLERS, REQUIRED
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
    from .config import experiment_from_data
    from .sweep import apply_settings
    data = apply_settings(copy.deepcopy(family.data[family.proposed]), sections)
    if settings:
        apply_settings(data, settings)
    return experiment_from_data(data, where)


def _probe(family: Family, sections: dict) -> str:
    """'' when the combination runs its first steps, else why not (an error other than divergence)."""
    from .config import build_loop
    from .core.simulation import simulate
    from .errors import ConfigError, Diverged
    base = family.data[family.proposed]["/**"]["ros__parameters"]
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
    from .config import CONTROLLERS, ESTIMATORS, SERVOS
    catalogue = catalogue if catalogue is not None else _catalogue_estimators(scenario_families())
    servo_sets = _servo_sets(family)
    direct = {label: all(SERVOS.entry(s["law"]).direct for s in servos.values())
              for label, servos in servo_sets.items()}
    own_estimator = _params(family.data[family.proposed], "/contour_estimator")["type"]
    combos, excluded = [], []
    for controller in CONTROLLERS.names():
        entry = CONTROLLERS.entry(controller)
        estimators = [own_estimator] if controller == "none" else ESTIMATORS.names()
        usable = {label for label in servo_sets if direct[label] == entry.whole_command}
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
        for estimator in estimators:
            for label in servo_sets:
                if label not in usable:
                    continue
                problems = []
                for section in seed:
                    sections = {"/contour_estimator": _estimator_section(family, estimator, catalogue),
                                "/ccc": section, **servo_sets[label]}
                    problems.append(_probe(family, sections))
                    if not problems[-1]:
                        combos.append(Combination(estimator, controller, label, sections,
                                                  _gain_keys(controller, section)))
                        break
                else:
                    excluded.append(Excluded(estimator, controller, label, problems[0]))
    return combos, excluded


# ---------------------------------------------------------------------------------------------- tuning


@dataclass
class Point:
    """One run of the tuning grid."""

    factor: float
    whole: object = None          # Scores of the whole run, None when it diverged
    steady: object = None         # Scores from the scenario's from_time
    failure: str = ""
    vectorised: bool = False      # it ran in a vectorised batch

    @property
    def effort(self) -> float:
        if self.whole is None:
            return math.inf
        return float(np.sqrt(np.mean(np.square(self.whole.effort_rms))))


def select(points: list, effort_limit: float) -> tuple:
    """(index of the admissible point with the lowest steady-state TACE, or None; why none when None).
    Admissible: it did not diverge and its RMS effort is at most ``effort_limit``."""
    scored = [i for i, p in enumerate(points) if p.steady is not None and p.whole is not None
              and math.isfinite(p.steady.tace)]
    if not scored:
        failures = sorted({p.failure.split(":")[0] for p in points if p.failure})
        return None, "diverged at every grid point" + (f" ({'; '.join(failures)})" if failures else "")
    admissible = [i for i in scored if points[i].effort <= effort_limit * (1.0 + 1e-12)]
    if not admissible:
        least = min(points[i].effort for i in scored)
        return None, (f"over the effort bound at every grid point that did not diverge (least effort "
                      f"{least / effort_limit:.3g} x the bound)")
    return min(admissible, key=lambda i: points[i].steady.tace), ""


@dataclass
class Row:
    family: Family
    combination: Combination | None
    excluded: Excluded | None = None
    points: list = field(default_factory=list)
    best: int | None = None
    status: str = ""
    reference: "Row | None" = None         # the proposed combination's row of the scenario (tuned)
    published: Point | None = None         # the proposed method with the file's gains

    @property
    def label(self) -> str:
        return (self.combination or self.excluded).label

    @property
    def is_proposed(self) -> bool:
        return self.reference is self

    @property
    def point(self) -> Point | None:
        return self.points[self.best] if self.best is not None else None

    @property
    def gains(self) -> dict:
        if self.point is None:
            return {}
        scaled = _scaled(self.combination.sections["/ccc"], self.combination.gain_keys, self.point.factor)
        return {k: scaled[k] for k in self.combination.gain_keys}

    def ratio(self, metric: str) -> float | None:
        """This row's steady-state ``metric`` (mce, tace, effort) over the proposed combination's (tuned)."""
        ref = self.reference.point if self.reference else None
        if self.point is None or ref is None:
            return None
        if metric == "effort":
            return self.point.effort / ref.effort if ref.effort > 0 else None
        mine, theirs = getattr(self.point.steady, metric), getattr(ref.steady, metric)
        return mine / theirs if theirs > 0 else None


def _bench_chunk(experiments: list, from_times: list) -> list:
    from .sweep import _score_one, simulate_experiments
    with np.errstate(all="ignore"):
        loops, results, alone, failures = simulate_experiments(experiments)
        out = []
        for loop, result, why, failure, from_time in zip(loops, results, alone, failures, from_times):
            if result is None:
                out.append((None, None, failure, not why))
                continue
            whole, failure = _score_one(loop, result, 0.0)
            steady = whole
            if whole is not None and from_time > 0.0:
                steady, failure = _score_one(loop, result, from_time)
            out.append((whole, steady if whole is not None else None, failure, not why))
        return out


def _score_all(experiments: list, from_times: list, workers: int, progress: bool) -> list:
    from tqdm import tqdm
    from .sweep import _chunks
    chunks = _chunks(experiments, workers, BATCH)
    out = [None] * len(experiments)
    with ProcessPoolExecutor(max_workers=workers) as pool, \
            tqdm(total=len(experiments), desc="benchmark", disable=not progress, leave=False) as bar:
        jobs = pool.map(_bench_chunk, [[experiments[i] for i in c] for c in chunks],
                        [[from_times[i] for i in c] for c in chunks])
        for chunk, results in zip(chunks, jobs):
            for i, result in zip(chunk, results):
                out[i] = result
            bar.update(len(chunk))
    return out


def run_benchmark(families: list, budget: int = DEFAULT_BUDGET, workers: int | None = None,
                  progress: bool = False, say=None) -> list:
    """Every row (one per scenario x combination, the excluded ones included) of ``families``."""
    say = say or (lambda message: None)
    workers = workers or os.cpu_count() or 1
    catalogue = _catalogue_estimators(scenario_families() if families else [])
    grid = factors(budget)
    rows, experiments, from_times, owners = [], [], [], []
    for family in families:
        combos, excluded = plan(family, catalogue)
        say(f"{family.name}: {len(combos)} combinations x {len(grid)} gains, {len(excluded)} cannot be paired")
        family_rows = []
        for combo in combos:
            row = Row(family, combo)
            points = grid if combo.gain_keys else [1.0]
            for factor in points:
                sections = dict(combo.sections, **{"/ccc": _scaled(combo.sections["/ccc"], combo.gain_keys, factor)})
                experiments.append(_experiment(family, sections, f"{family.name} {combo.label} x{factor:g}"))
                from_times.append(family.from_time)
                owners.append(row)
                row.points.append(Point(factor))
            family_rows.append(row)
        rows += family_rows + [Row(family, None, e, status=f"cannot be paired: {e.reason}") for e in excluded]
    results = _score_all(experiments, from_times, workers, progress)
    cursor = {}
    for row, (whole, steady, failure, vectorised) in zip(owners, results):
        j = cursor.get(id(row), 0)
        cursor[id(row)] = j + 1
        point = row.points[j]
        point.whole, point.steady, point.failure, point.vectorised = whole, steady, failure, vectorised
    for family in families:
        mine = [r for r in rows if r.family is family and r.combination]
        proposed = _proposed_row(family, mine)
        published = next((p for p in proposed.points if math.isclose(p.factor, 1.0)), None) if proposed else None
        limit = EFFORT_BOUND * published.effort if published and published.whole is not None else math.inf
        for row in mine:
            row.best, why = select(row.points, limit)
            row.status = why or "ok"
            row.reference, row.published = proposed, published
    return rows


def _proposed_row(family: Family, rows: list) -> Row | None:
    data = family.data[family.proposed]
    estimator = _params(data, "/contour_estimator")["type"]
    controller = _params(data, "/ccc")["type"]
    axes = data["/**"]["ros__parameters"]["axes"]
    servos = {f"/{a}/servo": _params(data, f"/{a}/servo") for a in axes}
    return next((r for r in rows if r.combination.estimator == estimator and r.combination.controller == controller
                 and all(r.combination.sections[k] == v for k, v in servos.items())), None)


# ---------------------------------------------------------------------------------------------- output


def _um(value) -> str:
    return "" if value is None else f"{value * 1e6:.6g}"


def _num(value) -> str:
    return "" if value is None or not math.isfinite(value) else f"{value:.6g}"


def write_csv(rows: list, path) -> Path:
    """One row per scenario x combination (lengths in micrometres; ratios to the proposed combination,
    tuned alike, from the scenario's steady state)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    head = ["paper", "scenario", "proposed_file", "estimator", "controller", "servo", "proposed", "status",
            "from_s", "gain_factor", "gains", "admissible_points", "grid_points", "mce_um", "tace_um", "rms_um",
            "mce_steady_um", "tace_steady_um", "rms_steady_um", "effort_rms", "mce_ratio", "tace_ratio",
            "effort_ratio", "tace_ratio_to_published"]
    with open(path, "w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(head)
        for row in rows:
            c = row.combination or row.excluded
            p = row.point
            whole, steady = (p.whole, p.steady) if p else (None, None)
            limit = EFFORT_BOUND * row.published.effort if row.published and row.published.whole else math.inf
            admissible = sum(1 for q in row.points if q.steady is not None and q.effort <= limit * (1 + 1e-12))
            published = row.published.steady.tace if row.published and row.published.steady else None
            writer.writerow([
                row.family.paper, row.family.name, row.family.proposed, c.estimator, c.controller, c.servo,
                "yes" if row.is_proposed else "", row.status, f"{row.family.from_time:g}",
                _num(p.factor) if p else "", json.dumps(row.gains) if p else "", admissible, len(row.points),
                _um(whole.mce if whole else None), _um(whole.tace if whole else None),
                _um(whole.rms if whole else None), _um(steady.mce if steady else None),
                _um(steady.tace if steady else None), _um(steady.rms if steady else None),
                _num(p.effort) if p else "", _num(row.ratio("mce")), _num(row.ratio("tace")),
                _num(row.ratio("effort")),
                _num(steady.tace / published) if steady and published else ""])
    return path


def _column(combination: Combination) -> tuple:
    """A heatmap column: (controller, estimator); the uncoupled controller reads no estimate: one column."""
    return (combination.controller, "-" if combination.controller == "none" else combination.estimator)


def _column_order(rows: list) -> list:
    from .config import CONTROLLERS, ESTIMATORS
    controllers, estimators = CONTROLLERS.names(), ESTIMATORS.names()
    pairs = {_column(r.combination) for r in rows if r.combination}
    return sorted(pairs, key=lambda p: (controllers.index(p[0]) if p[0] in controllers else 99,
                                        estimators.index(p[1]) if p[1] in estimators else 99))


def draw_heatmap(rows: list, path) -> Path:
    """Scenario (and servo) x estimator + controller: colour = log10 of the steady-state TACE over the
    proposed combination's (tuned alike); grey: cannot be paired; x: no admissible gain."""
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
            ratio = row.ratio("tace") if row else None
            if ratio is not None and ratio > 0:
                values[i, j] = math.log10(ratio)
    fig, ax = plt.subplots(figsize=(2.2 + 0.55 * len(columns), 1.6 + 0.32 * len(keys)))
    ax.set_facecolor("#dddddd")
    image = ax.imshow(np.clip(values, -2, 2), cmap="RdBu_r", norm=TwoSlopeNorm(0.0, -2.0, 2.0), aspect="auto")
    for i, (family, servo) in enumerate(keys):
        for j, (controller, estimator) in enumerate(columns):
            row = cells.get((family, servo, controller, estimator))
            if row is None:
                continue
            if row.point is None:
                ax.text(j, i, "x", ha="center", va="center", fontsize=8, color="black")
            else:
                ratio = row.ratio("tace")
                if ratio is not None:
                    ax.text(j, i, f"{ratio:.2g}", ha="center", va="center", fontsize=6,
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
    bar.set_label("log10 (TACE / proposed method's TACE), steady state, both tuned alike")
    ax.set_title("Contouring benchmark: TACE relative to each scenario's proposed method (boxed); "
                 "blue: lower. Grey: cannot be paired, x: no admissible gain", fontsize=9)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def paper_best(rows: list, family: Family) -> tuple:
    """(the proposed row, the best other row): the row with the lowest larger ratio of MCE and TACE to the
    proposed combination among those whose RMS effort is at most EQUAL_EFFORT times the proposed's (equal
    or lower effort; when there is none, among all with an admissible gain)."""
    mine = [r for r in rows if r.family is family and r.combination and r.point is not None]
    proposed = next((r for r in mine if r.is_proposed), None)
    if proposed is None:
        return None, None
    others = [r for r in mine if not r.is_proposed and r.ratio("effort") is not None]
    candidates = [r for r in others if r.ratio("effort") <= EQUAL_EFFORT] or others
    best = min(candidates, key=lambda r: (max(r.ratio("mce"), r.ratio("tace")), r.ratio("tace")), default=None)
    return proposed, best


def _f(value, digits=3) -> str:
    return "-" if value is None else f"{value:.{digits}g}"


def _best_table(rows: list, families: list) -> list:
    lines = ["| scenario | proposed (tuned) | proposed TACE / MCE [um] | best at equal or lower effort | "
             "TACE / MCE [um] | MCE ratio | TACE ratio | effort ratio | 2x in both |",
             "|---|---|---:|---|---:|---:|---:|---:|---|"]
    for family in families:
        proposed, best = paper_best(rows, family)
        if proposed is None:
            lines.append(f"| {family.name} | `{family.proposed}`: no result | | | | | | | |")
            continue
        ps = proposed.point.steady
        here = f"| {family.name} | {proposed.label} | {_f(ps.tace * 1e6)} / {_f(ps.mce * 1e6)} "
        if best is None:
            lines.append(here + "| no other combination | | | | | no |")
            continue
        bs = best.point.steady
        equal = best.ratio("effort") <= EQUAL_EFFORT
        met = best.ratio("mce") <= GOAL and best.ratio("tace") <= GOAL and equal
        lines.append(here + f"| {best.label}{'' if equal else ' (more effort: none at equal effort)'} | "
                     f"{_f(bs.tace * 1e6)} / {_f(bs.mce * 1e6)} | {_f(best.ratio('mce'))} | "
                     f"{_f(best.ratio('tace'))} | {_f(best.ratio('effort'))} | {'**yes**' if met else 'no'} |")
    return lines


def _family_table(rows: list, family: Family, top: int = 6) -> list:
    mine = [r for r in rows if r.family is family and r.combination]
    ranked = sorted([r for r in mine if r.point], key=lambda r: r.point.steady.tace)
    shown = ranked[:top]
    for r in mine:
        if (r.is_proposed or r.combination.controller == "none") and r not in shown:
            shown.append(r)
    lines = [f"Steady state from t = {family.from_time:g} s; proposed file `{family.proposed}` "
             f"({len(mine)} combinations, {len(ranked)} with an admissible gain; the best {min(top, len(ranked))}, "
             f"the proposed and the uncoupled ones):", "",
             "| combination | gains (tuned) | TACE [um] | MCE [um] | RMS [um] | TACE ratio | MCE ratio | effort ratio |",
             "|---|---|---:|---:|---:|---:|---:|---:|"]
    for r in shown:
        s = r.point.steady if r.point else None
        name = f"**{r.label}** (proposed)" if r.is_proposed else r.label
        gains = ", ".join(f"{k} {_fmt(v)}" for k, v in r.gains.items()) or "-"
        if s is None:
            lines.append(f"| {name} | - | {r.status} | | | | | |")
        else:
            lines.append(f"| {name} | {gains} | {_f(s.tace * 1e6)} | {_f(s.mce * 1e6)} | {_f(s.rms * 1e6)} | "
                         f"{_f(r.ratio('tace'))} | {_f(r.ratio('mce'))} | {_f(r.ratio('effort'))} |")
    return lines


def _fmt(value) -> str:
    if isinstance(value, list):
        return "[" + ", ".join(f"{v:.3g}" for v in value) + "]"
    return f"{value:.3g}"


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


def benchmark_report(rows: list, families: list, budget: int, seconds: float, command: str,
                     heatmap: str = "benchmark_heatmap.png", notes: dict | None = None, cpu: float = 0.0) -> str:
    """reports/benchmark.md: header, fairness rules, per paper the best combination against the proposed
    method, per scenario the leading combinations, the pairs that cannot be paired."""
    notes = notes or {}
    compatible = [r for r in rows if r.combination]
    runs = sum(len(r.points) for r in compatible)
    vectorised = sum(p.vectorised for r in compatible for p in r.points)
    top = max(factors(budget))
    tuned = [r for r in compatible if r.point is not None and r.combination.gain_keys]
    at_top = sum(math.isclose(r.point.factor, top) for r in tuned)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    grid = ", ".join(f"{f:.3g}" for f in factors(budget))
    lines = [
        "# Contouring benchmark: every estimator and controller on every scenario, tuned alike", "",
        f"Generated by `{command}` in {seconds / 60:.1f} min on {os.cpu_count()} cores (load average "
        f"{load:.1f} at the end; {cpu / 60:.1f} min of CPU time, so about {cpu / 60 / (os.cpu_count() or 1):.0f} "
        f"min on an idle machine of these cores; in-process simulation, vectorised batches): {len(families)} scenarios of "
        f"{len({f.paper for f in families})} papers, {len(compatible)} combinations ({runs} runs), "
        f"{len(rows) - len(compatible)} pairings that cannot be made. Budget {budget}: gain factors {grid}. "
        "Every figure in micrometres is the exact contour error (distance to the whole curve) from the scenario's "
        "steady-state start; ratios are to the scenario's proposed method tuned by the same rule (lower: better). "
        "All rows, with the tuned gains and whole-run scores: [benchmark.csv](benchmark.csv).", "",
        f"{vectorised} of the {runs} runs advanced in vectorised batches, the others one by one (classes without "
        f"a batch path, or a batch with a member that overflowed). {at_top} of the {len(tuned)} tuned combinations "
        f"chose the grid's largest factor ({top:g}): their best gains may lie beyond it (a larger budget or span "
        "refines them; the effort bound and divergence are what stop the others).", "",
        "## Fairness rules", "",
        "- **Scenarios**: the paper files that share the curve, schedule, timing and plants are one scenario; the "
        "benchmark runs the scenario's proposed file with the method swapped. The proposed method is the file a "
        "claim of `config/claims/` proposes, else the file with a proposed file's servo, estimator and controller. "
        "The steady state starts at the claims' `from_time` (the largest on the scenario's files).",
        "- **Combinations**: every estimator x controller of the registries (entry-point plugins included) x every "
        "servo set the scenario's files define (servos are the scenario's own, tuned to its plants; none is "
        "invented). Each estimator and controller starts from the scenario's own section of its type; an "
        "estimator the scenario does not use takes its first section in any scenario file; a controller it does "
        "not use takes the gains of a scenario controller with the same parameters (same units), else it cannot "
        "be paired. The uncoupled controller `none` reads no estimate and is run with the scenario's estimator.",
        f"- **Tuning rule, the same for all**: the controller's gains ({_gain_list()}) "
        f"are scaled together by one factor on a log grid of {budget} points from 1/{SPAN:g} to {SPAN:g} around "
        "the file's own gains (1 always included); estimators and servos keep their sections. Scaling every gain "
        "together keeps a PID's zeros and the task-frame PD's damping ratios (its bandwidths are scaled).",
        f"- **Effort bound**: a run is admissible if it did not diverge and its RMS actuator effort (RMS over the "
        f"axes of each axis' RMS command) is at most {EFFORT_BOUND:g} x that of the scenario's proposed method "
        "with the file's gains. The admissible run with the lowest steady-state TACE is the combination's "
        "result; diverged runs never win.",
        "- **Best versus proposed**: per scenario, among the combinations whose tuned RMS effort is at most "
        f"{EQUAL_EFFORT:g} x the tuned proposed method's (equal, within {100 * (EQUAL_EFFORT - 1):.0f}%, or lower "
        "effort), the one with the lowest larger ratio of MCE and TACE (steady state); the goal (beat the proposed "
        f"method 2x) needs both ratios <= {GOAL:g} at equal or lower effort.",
        "- **Pairings that cannot be made** are listed at the end with the reason (validation's, the scenario's, "
        "or the first steps' error).", "",
        f"![TACE relative to the proposed method]({heatmap})", "",
        "## Per paper: the best combination against the proposed method", ""]
    for paper in sorted({f.paper for f in families}):
        mine = [f for f in families if f.paper == paper]
        lines += [f"### Paper {paper}", ""] + _best_table(rows, mine) + [""]
        if paper in notes:
            lines += [notes[paper].strip(), ""]
    lines += ["## Per scenario", ""]
    for family in families:
        lines += [f"### {family.name}", ""] + _family_table(rows, family) + [""]
    lines += ["## Pairings that cannot be made", ""] + _excluded_table(rows) + [""]
    return "\n".join(lines)


def _gain_list() -> str:
    return "; ".join(f"{name}: {', '.join(keys)}" for name, keys in GAIN_KEYS.items() if keys)


def read_notes(path) -> dict:
    """Paper -> the findings paragraph written for it (config/benchmark/notes.yaml), if the file exists."""
    path = Path(path)
    if not path.is_file():
        return {}
    data = yaml.safe_load(path.read_text()) or {}
    return {str(k): str(v) for k, v in data.items()}


def main_benchmark(patterns=None, budget: int = DEFAULT_BUDGET, out="reports", workers=None, progress=False,
                   say=None, command: str = "contouring-ros benchmark") -> tuple:
    """Run the benchmark and write benchmark.md, benchmark.csv and benchmark_heatmap.png into ``out``."""
    from .paper import CONFIG_DIR
    import resource
    start = time.perf_counter()
    families = select_families(scenario_families(), patterns)
    rows = run_benchmark(families, budget, workers, progress, say)
    out = Path(out)
    csv_path = write_csv(rows, out / "benchmark.csv")
    png = draw_heatmap(rows, out / "benchmark_heatmap.png")
    seconds = time.perf_counter() - start
    cpu = sum(resource.getrusage(who).ru_utime + resource.getrusage(who).ru_stime
              for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    text = benchmark_report(rows, families, budget, seconds, command, png.name,
                            read_notes(CONFIG_DIR / "benchmark" / "notes.yaml"), cpu)
    md = out / "benchmark.md"
    md.write_text(text + "\n")
    return md, csv_path, png, seconds
