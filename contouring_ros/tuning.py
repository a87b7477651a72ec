"""Fair tuning: every gain of a method tuned on its own, by one optimiser, under the same constraints, on a
machine with the imperfections every real feed drive has; its result given with an interval.

How control engineers compare controllers (Åström & Hägglund, Advanced PID Control, ISA, 2006, ch. 7;
Garpinger & Hägglund, "Software-based optimal PID design with robustness and noise sensitivity
constraints", J. Process Control 33, 2015): at equal robustness and equal noise sensitivity, not at equal
gains; performance is then the error. Here, per combination (estimator x contour controller x servo set of a
scenario):

Machine. The scenario runs on a *realistic* machine (:data:`REALISTIC`): an encoder of 0.1 um, 0.05 um RMS
of position noise, one sample of computation delay and velocity from the differentiated encoder (Altintas,
Manufacturing Automation, 2nd ed., 2012, ch. 5-6: encoders of 0.1-1 um, servo loops at 1 kHz with velocity
from the encoder), and an actuator limit: the paper's where its file states one, else
:data:`SATURATION_MARGIN` times the largest command the proposed method needs with the paper's gains on the
ideal machine. A key the scenario file sets itself is kept. The ideal machine (none of these) stays
available for comparison.

Search. Every gain of the controller (:func:`gain_keys`) is a variable of its own on a log10 scale,
:attr:`Protocol.decades` decades either side of its anchor: the file's value, or for a gain that is 0 in the
file an anchor from its sibling (ki: 30 kp, kd: 1e-3 kp) so that it is free to become non-zero; the lower
end of the span means 0 (off). The same budget of evaluations for every method. The file's own gains are the first
evaluation, so a tuned result is never worse than the file's when that is admissible; a coarse scan of
every gain scaled together (:attr:`Protocol.scan` decades) comes next, so a paper whose gains sit decades
from where its loop acts is not tuned short, then :attr:`Protocol.design` quasi-random points (scrambled
Sobol, scipy.stats.qmc) over the whole box, which reach basins where one gain is off or decades from its
siblings. From the best of these :func:`minimise` spends the rest: CMA-ES (Hansen, "The CMA evolution
strategy: a tutorial", 2016; the ``cma`` package) for a global search, each population run as one batch,
then Nelder-Mead (scipy) to converge from its best point. With :attr:`Protocol.searches` K > 1 the search
runs K times (seeds ``seed`` to ``seed + K - 1``: other Sobol points and CMA-ES samples) and the one that
ended best by its own measure is kept (:func:`best_search`); the draws run once, for its gains.

Constraints (the same for every method of a scenario, measured in simulation):

- stable: the run did not diverge;
- noise sensitivity: the RMS of the command's sample-to-sample change in the steady state (RMS over the
  axes) at most :attr:`Protocol.noise_factor` times the proposed method's with the paper's gains on the
  same machine and seed;
- saturation: at most :attr:`Protocol.saturation_share` of the steady-state steps with an axis' command
  at or beyond its limit;
- peak sensitivity, where the loop is linear (PID, PID + feedforward and cascade servos with a linear
  contour controller; :func:`loop_robustness`): the closed loop stable and Ms at most :data:`MS_LIMIT`
  (Åström & Hägglund's 1.4-2), or the drive's own Ms where its servo alone already exceeds that; a point
  beyond it is refused before it runs;
- robustness: with each plant parameter (gain, time constant, mass, damping) at plus and minus
  :attr:`Protocol.perturbation` on every axis, the run stays stable and its steady-state TACE within
  :attr:`Protocol.robust_factor` times the nominal one, or no worse than the proposed method's worst TACE
  there with the paper's gains (the same robustness as the paper's own design is enough: where that design
  itself degrades by more than the factor, a rule relative to a point's own error alone would pass only
  points far worse than the paper's, whose large error hides their degradation). Checked at once on every
  admissible point that beats the robust best by more than :attr:`Protocol.robust_step` (a point that
  fails is inadmissible and its objective pays, so the search turns away from gains that work only on the
  nominal plant); the smaller improvements after the search, best first (:attr:`Protocol.final_checks`).
  Where no point is robust, the best point backed off a quarter decade at a time, else the checked point
  with the lowest worst case, marked "not robust".

Objective: the steady-state TACE of the exact contour error (median seed).

Interval. The tuned gains then run :attr:`Protocol.draws` times, draw j with noise seed j, a model
mismatch drawn uniformly within +-:attr:`Protocol.mismatch` of every plant parameter and a disturbance
phase (:func:`draw_settings`) (the same draws for
every method of the scenario, so ratios are paired draw by draw); the report gives the median and the
2.5-97.5 percentile interval of each figure and ratio.
"""
from __future__ import annotations

import copy
import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from .experiment.build import build_controller, build_curve, build_plant, build_servo
from .experiment.catalogue import CONTROLLERS, PLANTS, SERVOS
from .experiment.validate import experiment_from_data
from .experiment.schema import GLOBAL_SECTION
from .core.margins import axis_loop, coupled_loop, margins, quick_robustness
from .errors import ConfigError
from .learning import passes, simulate_last_passes
from .sweep import apply_settings, score_one, simulate_experiments

__all__ = ["REALISTIC", "SATURATION_MARGIN", "varied_parameters", "Protocol", "Outcome",
           "Evaluation", "Tuned", "gain_keys", "anchors", "machine_settings", "perturbations", "draw_settings",
           "experiment_for", "fit_to_machine", "section_with_gains",
           "experiment_margins", "worst_margins", "loop_robustness", "MS_LIMIT", "run_outcomes", "worst_case", "minimise",
           "nelder_mead_restarts", "Search", "best_search", "tune", "interval", "pareto_front"]

#: plant keys of the realistic machine (a key the scenario file sets is kept)
REALISTIC = {"encoder_resolution": 1e-7, "measurement_noise": 5e-8, "command_delay": 1,
             "velocity_measurement": "encoder"}
#: the actuator limit, where the paper states none: this times the proposed method's largest command
SATURATION_MARGIN = 2.0
#: the anchor of a gain that is 0 in the file, relative to its sibling (same units as the PID's)
SIBLING_ANCHOR = {"ki": ("kp", 30.0), "kd": ("kp", 1e-3)}
MS_LIMIT = 2.0      # peak sensitivity a linear loop may reach (Åström & Hägglund: 1.4-2)
OFF = 0.05          # decades above the lower end of a gain's span that mean "off" (0)
PENALTY = 10.0      # objective added per decade (log10) a constraint is exceeded by; diverged: 100


@dataclass(frozen=True)
class Protocol:
    """The tuning protocol: the same numbers for every method of a benchmark."""

    evaluations: int = 100         # evaluations per combination (the file's gains included)
    popsize: int = 6
    decades: float = 8.0           # each gain's span either side of its anchor [decades]
    scan: tuple = (-2.0, 2.0, 4.0, 6.0)  # decades every gain is shifted by together in the first scan
    noise_factor: float = 2.0      # noise sensitivity at most this x the proposed method's (paper's gains)
    saturation_share: float = 0.01  # share of steady-state steps at the actuator limit, at most
    perturbation: float = 0.2      # robustness: each plant parameter x (1 +- this)
    robust_factor: float = 3.0     # ... with steady-state TACE at most this x the larger of the nominal and the floor
    robust_step: float = 0.05      # a point that beats the robust best by more than this share is checked at once
    final_checks: int = 3          # ... the others after the search, best first, at most this many
    design: int = 8                # quasi-random points (scrambled Sobol) over the whole box after the scan
    backoff: int = 4               # no robust point found: the best with every gain lowered a quarter decade at a time
    ms_limit: bool = True          # refuse points whose linear loop has Ms over MS_LIMIT (see loop_robustness)
    draws: int = 8                 # noise seeds x model-mismatch draws of the interval
    mismatch: float = 0.1          # model mismatch of a draw: each plant parameter x U(1 - this, 1 + this)
    seed: int = 1                  # CMA-ES seed (and the Sobol points'); search i of searches uses seed + i
    searches: int = 1              # independent searches per combination; the best of them is kept (:func:`best_search`)
    global_share: float = 0.5      # share of the evaluations for CMA-ES; the rest polish with Nelder-Mead
    polish_step: float = 0.3       # Nelder-Mead's first simplex [decades]
    global_step: float = 2.0       # CMA-ES's first step [decades]

    def describe(self) -> str:
        return (f"{self.evaluations} evaluations: the file's gains, the file's gains scaled together by "
                f"10^({', '.join(f'{d:+g}' for d in self.scan)}), {self.design} scrambled-Sobol points over the whole "
                f"box, then CMA-ES (population {self.popsize}, first step {self.global_step:g} decades) for "
                f"{100 * self.global_share:.0f}% of the rest, then Nelder-Mead from its best point; each gain "
                f"log-scaled over +-{self.decades:g} decades of its anchor; noise sensitivity <= {self.noise_factor:g} "
                f"x the proposed method's; <= {100 * self.saturation_share:g}% of steps saturated; "
                f"{f'linear loops stable with Ms <= {MS_LIMIT:g}; ' if self.ms_limit else ''}robust: stable at "
                f"+-{100 * self.perturbation:g}% of each plant parameter with TACE <= {self.robust_factor:g} x "
                f"nominal, or no worse than the proposed method's worst there with the paper's gains; "
                f"{self.draws} draws (noise seed, +-{100 * self.mismatch:g}% model mismatch)"
                + (f"; the best of {self.searches} such searches (seeds {self.seed} to {self.seed + self.searches - 1}: "
                   f"the robust chosen point with the lowest nominal TACE)" if self.searches > 1 else ""))


@dataclass(frozen=True)
class Outcome:
    """One run's figures (steady state unless said); ``failure`` is set (and the figures nan) when it diverged."""

    tace: float = math.nan
    mce: float = math.nan
    rms: float = math.nan
    noise: float = math.nan        # RMS of the command's sample-to-sample change (RMS over axes)
    saturated: float = math.nan    # share of steps with an axis' command at or beyond its limit
    effort: float = math.nan       # RMS command (RMS over axes), whole run
    peak_command: tuple = ()       # largest |command| per axis, whole run
    failure: str = ""

    @property
    def ok(self) -> bool:
        return not self.failure


@dataclass
class Evaluation:
    """One point of the search."""

    gains: dict
    outcome: Outcome
    objective: float
    admissible: bool
    worst: float = math.nan        # the worst steady-state TACE over the robustness runs (nan: not checked)


@dataclass
class Tuned:
    """A combination's tuned result."""

    gains: dict = field(default_factory=dict)
    file_gains: dict = field(default_factory=dict)
    at_bound: list = field(default_factory=list)       # gains at an end of their span (not an optimum there)
    evaluations: list = field(default_factory=list)    # every Evaluation of the search, in order
    nominal: Outcome | None = None                     # the tuned gains, seed 0, nominal plant
    robust_worst: float = math.nan                     # worst TACE over the +-perturbation runs / nominal
    robustness_runs: int = 0
    draws: list = field(default_factory=list)          # Outcome per draw
    ideal: Outcome | None = None                       # the tuned gains on the ideal machine
    margins: object = None                             # worst_margins of the tuned loop on the machine, if linear
    status: str = "ok"
    cpu: float = math.nan                              # CPU seconds the tuning, its checks and draws took
    search: int = 0                                    # which of the Protocol.searches searches was kept
    search_tace: list = field(default_factory=list)    # each search's chosen nominal TACE [m] (nan: none)

    @property
    def ok(self) -> bool:
        return self.nominal is not None and self.status == "ok"


# ------------------------------------------------------------------------------------------ gains


def gain_keys(controller: str, section: dict) -> tuple:
    """The gains of a controller section that the tuning varies (those the section sets): its catalogue
    entry's ``gains``; where the entry names none (a plugin's), its float parameters whose names start
    with 'k'."""
    entry = CONTROLLERS.entry(controller)
    keys = entry.gains
    if keys is None:
        keys = tuple(k for k, p in entry.params.items() if p.kind in ("float", "floats") and k.startswith("k"))
    return tuple(k for k in keys if section.get(k) is not None)


def varied_parameters(model) -> tuple:
    """The physical parameters of a plant type that robustness runs and model-mismatch draws vary: its
    catalogue entry's ``varied`` (none for a type not known)."""
    return PLANTS.entry(model).varied if isinstance(model, str) and model in PLANTS else ()


def _magnitude(value) -> float:
    values = [abs(float(v)) for v in (value if isinstance(value, list) else [value])]
    return max(values) if values else 0.0


def anchors(section: dict, keys: tuple) -> dict:
    """key -> the gain's anchor: its magnitude in the file (a per-axis list: its largest entry), else
    :data:`SIBLING_ANCHOR` from a sibling, else 1."""
    out = {}
    for key in keys:
        value = _magnitude(section[key])
        if value > 0.0:
            out[key] = value
            continue
        sibling, ratio = SIBLING_ANCHOR.get(key, (None, 1.0))
        base = _magnitude(section.get(sibling, 0.0)) if sibling else 0.0
        out[key] = base * ratio if base > 0.0 else 1.0
    return out


def _set_gain(section: dict, key: str, magnitude: float) -> None:
    """The gain ``key`` of ``section`` set to ``magnitude`` (a per-axis list keeps its proportions; a list
    of zeros becomes ``magnitude`` on every axis)."""
    value = section[key]
    if isinstance(value, list):
        top = _magnitude(value)
        section[key] = [magnitude * float(v) / top for v in value] if top > 0 else [magnitude] * len(value)
    else:
        section[key] = magnitude


def section_with_gains(section: dict, gains: dict) -> dict:
    """A copy of the controller ``section`` with the tuned ``gains`` (key -> magnitude, as a
    :class:`Tuned` and the benchmark's CSV give them) set."""
    out = dict(section)
    for key, magnitude in gains.items():
        _set_gain(out, key, magnitude)
    return out


def _gains_from(x, keys: tuple, anchor: dict, decades: float) -> dict:
    out = {}
    for key, xi in zip(keys, x):
        low = math.log10(anchor[key]) - decades
        out[key] = 0.0 if xi <= low + OFF else 10.0 ** float(xi)
    return out


# ---------------------------------------------------------------------------------------- machines


def _plants(data: dict) -> dict:
    """'/x/plant' -> its parameters, for every axis of the file."""
    axes = data[GLOBAL_SECTION]["ros__parameters"]["axes"]
    return {f"/{a}/plant": data[f"/{a}/plant"]["ros__parameters"] for a in axes}


def machine_settings(data: dict, kind: str, peak_command: tuple = ()) -> dict:
    """Grid settings (see :mod:`contouring_ros.sweep`) that put the file's plants on a machine ``kind``:
    'ideal' (no settings) or 'realistic' (:data:`REALISTIC`, each key the file does not set; an actuator
    limit of :data:`SATURATION_MARGIN` x ``peak_command`` of the axis where the file sets none)."""
    if kind == "ideal":
        return {}
    if kind != "realistic":
        raise ValueError(f"machine {kind!r}: expected ideal or realistic")
    settings = {}
    for i, (node, params) in enumerate(_plants(data).items()):
        where = node[1:]
        for key, value in REALISTIC.items():
            if not params.get(key):
                settings[f"{where}.{key}"] = value
        if "noise_seed" not in params:                     # noise independent between the axes
            settings[f"{where}.noise_seed"] = i
        if not params.get("saturation") and i < len(peak_command) and peak_command[i] > 0:
            settings[f"{where}.saturation"] = SATURATION_MARGIN * float(peak_command[i])
    return settings


def perturbations(data: dict, fraction: float) -> list:
    """Settings for the robustness runs: each plant parameter of :func:`varied_parameters` at (1 - fraction)
    and (1 + fraction) of its value, on every axis at once."""
    plants = _plants(data)
    keys = []
    for params in plants.values():
        for key in varied_parameters(params.get("model")):
            if key not in keys and params.get(key):
                keys.append(key)
    out = []
    for key in keys:
        for factor in (1.0 - fraction, 1.0 + fraction):
            out.append({f"{node[1:]}.{key}": float(params[key]) * factor for node, params in plants.items()
                        if params.get(key)})
    return out


def draw_settings(data: dict, j: int, mismatch: float) -> dict:
    """Draw ``j``'s settings: noise seeds from j, every plant parameter x U(1 - mismatch, 1 + mismatch), and
    from draw 1 on a sinusoidal disturbance's phase U(0, 2 pi) and a random disturbance's seed (drawn from j
    alone, so every method of a scenario meets the same draws)."""
    rng = np.random.default_rng(1000 + j)
    settings = {}
    for i, (node, params) in enumerate(_plants(data).items()):
        settings[f"{node[1:]}.noise_seed"] = 1 + j * 16 + i
        for key in varied_parameters(params.get("model")):
            factor = float(rng.uniform(1.0 - mismatch, 1.0 + mismatch))
            if params.get(key):
                settings[f"{node[1:]}.{key}"] = float(params[key]) * factor
        phase = float(rng.uniform(0.0, 2.0 * math.pi))
        disturbance = params.get("disturbance") or {}
        if j and disturbance.get("type") == "sinusoid":
            settings[f"{node[1:]}.disturbance.phase"] = phase
        elif j and disturbance.get("type") == "random":
            settings[f"{node[1:]}.disturbance.seed"] = int(disturbance.get("seed", 0)) + 7919 * j
    return settings


# -------------------------------------------------------------------------------------------- runs


def _outcomes(experiments: list, from_time: float, limits: list) -> list:
    """An :class:`Outcome` per experiment, ``limits[i]`` the actuator limits of experiment i's axes: those of
    one structure run as one vectorised batch where every class has a batch path
    (:func:`contouring_ros.sweep.simulate_experiments`), the others one by one. A learning experiment (more
    than one pass, :mod:`contouring_ros.learning`) runs every pass and is judged by its last: what the part
    is like once the correction has been learned; the learning experiments' passes run together, pass by
    pass (:func:`contouring_ros.learning.simulate_last_passes`)."""
    learning = [i for i, e in enumerate(experiments) if passes(e) > 1]
    rest = [i for i, e in enumerate(experiments) if passes(e) <= 1]
    out = [None] * len(experiments)
    with np.errstate(all="ignore"):
        loops, results, _, failures = simulate_experiments([experiments[i] for i in rest])
        for i, loop, result, failure in zip(rest, loops, results, failures):
            out[i] = Outcome(failure=failure) if result is None else _figures(loop, result, from_time, limits[i])
        last = simulate_last_passes([experiments[i] for i in learning])
        for i, (loop, result, failure) in zip(learning, last):
            out[i] = Outcome(failure=failure) if result is None else _figures(loop, result, from_time, limits[i])
    return out


def _figures(loop, result, from_time: float, limits: tuple) -> Outcome:
    scores, failure = score_one(loop, result, from_time)
    if scores is None:
        return Outcome(failure=failure)
    command = np.asarray(result.command, dtype=float)
    steady = command[result.time >= from_time - 1e-12]
    change = np.diff(steady, axis=0)
    noise = float(np.sqrt(np.mean(np.square(change)))) if change.size else 0.0
    limit = np.array([v if v > 0 else np.inf for v in limits] if limits else [np.inf] * command.shape[1])
    saturated = float(np.mean(np.any(np.abs(steady) >= limit * (1 - 1e-12), axis=1))) if len(steady) else 0.0
    return Outcome(scores.tace, scores.mce, scores.rms, noise, saturated,
                   float(np.sqrt(np.mean(np.square(command)))), tuple(float(v) for v in np.max(np.abs(command), 0)))


def _limits(data: dict, settings: dict) -> tuple:
    return tuple(float(settings.get(f"{node[1:]}.saturation", params.get("saturation") or 0.0))
                 for node, params in _plants(data).items())


def fit_to_machine(data: dict, sections: dict, machine: dict) -> dict:
    """``sections`` with what models the drive set to the machine's (``machine``: grid settings of
    :func:`machine_settings` over the plants of ``data``): a servo's or controller's ``command_delay`` the
    axis' computation delay (a controller: the largest), a controller's unset ``command_limit`` each axis'
    actuator limit (:func:`_limits`), and where the machine's velocity is the differentiated encoder, a
    controller's unset ``velocity_estimate`` 'model' (its observer, not the mean velocity of the last step).
    A method that models its drive is told the drive it runs on, as an engineer commissioning it would be."""
    plants = _plants(data)
    delay = {node: int(machine.get(f"{node[1:]}.command_delay", params.get("command_delay") or 0))
             for node, params in plants.items()}
    limit = list(_limits(data, machine))
    out = dict(sections)
    for node in plants:
        servo_node = node.replace("/plant", "/servo")
        servo = out.get(servo_node)
        if servo and "command_delay" in SERVOS.entry(servo["law"]).params:
            out[servo_node] = dict(servo, command_delay=delay[node])
    ccc = out.get("/ccc")
    if ccc and ccc.get("type") in CONTROLLERS:
        params = CONTROLLERS.entry(ccc["type"]).params
        ccc = dict(ccc)
        if "command_delay" in params:
            ccc["command_delay"] = max(delay.values())
        if "command_limit" in params and not any(ccc.get("command_limit") or ()) and any(limit):
            ccc["command_limit"] = limit
        encoder = any(machine.get(f"{node[1:]}.velocity_measurement", plant.get("velocity_measurement")) == "encoder"
                      for node, plant in plants.items())
        if "velocity_estimate" in params and "velocity_estimate" not in ccc and encoder:
            ccc["velocity_estimate"] = "model"
        out["/ccc"] = ccc
    return out


def experiment_for(data: dict, sections: dict, settings: dict, where: str):
    """The validated experiment of ``data`` (a parsed experiment file) with the node ``sections`` and the
    grid ``settings`` applied (ConfigError when refused)."""
    here = apply_settings(apply_settings(copy.deepcopy(data), sections), settings)
    return experiment_from_data(here, where)


def run_outcomes(data: dict, sections: dict, settings_list: list, from_time: float, where: str) -> list:
    """An :class:`Outcome` per settings mapping: :func:`experiment_for` each, simulated in-process (batched
    where the classes allow, :func:`_outcomes`)."""
    out, experiments, places = [], [], []
    for settings in settings_list:
        try:
            experiments.append(experiment_for(data, sections, settings, where))
            places.append(len(out))
            out.append(None)
        except ConfigError as error:
            out.append(Outcome(failure=f"refused: {error}"))
    for i, outcome in zip(places, _outcomes(experiments, from_time, [_limits(data, settings_list[i]) for i in places])):
        out[i] = outcome
    return out


def worst_case(data: dict, sections: dict, machine: dict, from_time: float, protocol: Protocol, where: str) -> float:
    """The worst steady-state TACE [m] of ``sections`` on ``machine`` over the robustness runs
    (:func:`perturbations`); inf where one diverges."""
    runs = run_outcomes(data, sections, [dict(machine, **c) for c in perturbations(data, protocol.perturbation)],
                        from_time, where)
    return max((r.tace if r.ok else math.inf) for r in runs) if runs else math.nan


def _loops(experiment) -> dict:
    """{axis: {"axis": L(z) | None, "coupled": L(z) | None}}: each axis' loop alone
    (:func:`contouring_ros.core.margins.axis_loop`) and with the experiment's contour controller
    (:func:`~contouring_ros.core.margins.coupled_loop`: each axis as if the others were identical to it, on
    a straight line); None where the law is not linear time-invariant feedback."""
    ts = float(experiment.sample_time)
    controller = build_controller(experiment, build_curve(experiment))
    out = {}
    for axis in experiment.axes:
        plant = build_plant(experiment, axis, 0.0, 0.0)
        servo = build_servo(experiment, axis, 0.0, 0.0, 0.0)
        out[axis] = {"axis": axis_loop(plant, servo, ts), "coupled": coupled_loop(plant, servo, controller, ts)}
    return out


def experiment_margins(experiment) -> dict:
    """The margins of every axis of an experiment: {axis: {"axis": LoopMargins | None, "coupled": ...}} of
    the loops of :func:`_loops`."""
    ts = float(experiment.sample_time)
    return {axis: {name: None if loop is None else margins(loop, ts) for name, loop in loops.items()}
            for axis, loops in _loops(experiment).items()}


def worst_margins(per_axis: dict):
    """The axis loop with the highest Ms among the coupled loops (else the axis loops) of
    :func:`experiment_margins`, or None when no loop is linear."""
    loops = [m["coupled"] for m in per_axis.values() if m["coupled"] is not None] or \
        [m["axis"] for m in per_axis.values() if m["axis"] is not None]
    return max(loops, key=lambda m: m.ms) if loops else None


# ------------------------------------------------------------------------------------------ search


def _objective(outcome: Outcome, noise_limit: float, protocol: Protocol) -> tuple:
    """(objective, admissible): log10 of the TACE in um, plus :data:`PENALTY` per decade a constraint is
    exceeded by; 100 for a run that diverged."""
    if not outcome.ok or not math.isfinite(outcome.tace):
        return 100.0, False
    value = math.log10(max(outcome.tace, 1e-15) * 1e6)
    excess = 0.0
    if math.isfinite(noise_limit) and outcome.noise > noise_limit:
        excess += math.log10(outcome.noise / noise_limit) + 0.1
    if outcome.saturated > protocol.saturation_share:
        excess += outcome.saturated - protocol.saturation_share + 0.1
    return value + PENALTY * excess, excess == 0.0


def minimise(objective, x0: list, low: list, high: list, evaluations: int, protocol: Protocol) -> tuple:
    """(best x, its value, evaluations used) of ``objective`` within the box [low, high] from ``x0``.

    Two phases within one budget of ``evaluations``: CMA-ES (Hansen 2016; the ``cma`` package) with a
    first step of :attr:`Protocol.global_step` units (decades on a log scale) for :attr:`Protocol.global_share`
    of it, a global search that can leave the start's basin; then Nelder-Mead (scipy.optimize, bounded) from the best point found, with a
    simplex of :attr:`Protocol.polish_step` units, which converges on the optimum (often on a constraint's
    edge) in few evaluations where CMA-ES would still be adapting its step. An ``objective`` with a ``many``
    attribute (a list of points -> their values) gets each CMA-ES population at once (one batch)."""
    import cma
    from scipy.optimize import minimize
    state = {"best": [float(v) for v in x0], "value": math.inf, "used": 0}

    def counted(x):
        return counted_many([x])[0]

    def counted_many(xs):
        if state["used"] + len(xs) > evaluations:
            raise _Spent
        state["used"] += len(xs)
        many = getattr(objective, "many", None)
        values = [float(v) for v in many(xs)] if many else [float(objective(x)) for x in xs]
        for x, value in zip(xs, values):
            if value < state["value"]:
                state["best"], state["value"] = [float(v) for v in x], value
        return values

    first = max(1, int(round(evaluations * protocol.global_share)))
    n = len(x0)
    pad = [0.0] if n == 1 else []         # cma cannot search one dimension: a second one, ignored
    options = {"bounds": [list(low) + [-1.0] * len(pad), list(high) + [1.0] * len(pad)],
               "popsize": protocol.popsize, "seed": protocol.seed, "verbose": -9, "tolx": 1e-3, "tolfun": 1e-6}
    step = min(protocol.global_step, 0.3 * float(np.min(np.subtract(high, low))))   # within the box's narrowest side
    es = cma.CMAEvolutionStrategy(list(x0) + pad, step, options)
    try:
        while not es.stop() and state["used"] + protocol.popsize <= first:
            xs = es.ask()
            es.tell(xs, counted_many([list(x[:n]) for x in xs]))
        start = np.asarray(state["best"], dtype=float)
        simplex = np.vstack([start] + [start + protocol.polish_step * e for e in np.eye(len(start))])
        simplex = np.clip(simplex, low, high)
        for i in range(1, len(simplex)):           # a vertex pushed onto the start by a bound steps back instead
            if np.array_equal(simplex[i], start):
                simplex[i, i - 1] -= protocol.polish_step
        minimize(counted, start, method="Nelder-Mead", bounds=list(zip(low, high)),
                 options={"maxfev": max(evaluations - state["used"], 1), "initial_simplex": simplex,
                          "xatol": 1e-3, "fatol": 1e-6})
    except _Spent:
        pass
    return state["best"], state["value"], state["used"]


def nelder_mead_restarts(objective, x0: list, low: list, high: list, evaluations: int, protocol: Protocol,
                         starts: int = 4) -> tuple:
    """(best x, its value, evaluations used): bounded Nelder-Mead (scipy) from ``x0`` and from
    ``starts`` - 1 points drawn uniformly in the box, the budget split evenly: an independent search to check
    :func:`minimise` against (SCIENCE: "Nelder-Mead from several starts")."""
    from scipy.optimize import minimize
    rng = np.random.default_rng(protocol.seed + 100)
    points = [np.asarray(x0, dtype=float)] + [rng.uniform(low, high) for _ in range(starts - 1)]
    best, value, used = list(x0), math.inf, 0
    for i, start in enumerate(points):
        share = (evaluations - used) // (len(points) - i)
        calls = []

        def counted(x):
            if len(calls) >= share:
                raise _Spent
            calls.append(1)
            return float(objective(x))
        simplex = np.clip(np.vstack([start] + [start + 1.0 * e for e in np.eye(len(start))]), low, high)
        for j in range(1, len(simplex)):
            if np.array_equal(simplex[j], start):
                simplex[j, j - 1] -= 1.0
        try:
            result = minimize(counted, start, method="Nelder-Mead", bounds=list(zip(low, high)),
                              options={"maxfev": share, "initial_simplex": simplex, "xatol": 1e-3, "fatol": 1e-6})
            if result.fun < value:
                best, value = [float(v) for v in result.x], float(result.fun)
        except _Spent:
            pass
        used += len(calls)
    return best, value, used


class _Spent(Exception):
    """The evaluation budget is spent."""


def loop_robustness(experiment) -> tuple | None:
    """(Ms, stable, allowed Ms) of the least robust linear loop of an experiment, fast enough to ask at every
    point of a search (:func:`contouring_ros.core.margins.quick_robustness`); None when no loop is linear.
    The loop is each axis coupled with a linear contour controller (:func:`experiment_margins`'s "coupled");
    allowed is :data:`MS_LIMIT`, or the axis loop's own Ms where the drive's servo alone already exceeds it
    (a contour controller must then not make it worse)."""
    worst = None
    for loops in _loops(experiment).values():
        if loops["coupled"] is None:
            continue
        ms, stable = quick_robustness(loops["coupled"])
        allowed = max(MS_LIMIT, quick_robustness(loops["axis"])[0]) if loops["axis"] is not None else MS_LIMIT
        here = (ms if stable else math.inf, stable, allowed)
        if worst is None or here[0] / here[2] > worst[0] / worst[2]:
            worst = here
    return worst


@dataclass
class Search:
    """What one search of :func:`tune` ends with: the chosen Evaluation (None: no admissible point), the
    status it gives the combination and the chosen point's worst TACE over the perturbations / its nominal."""

    chosen: Evaluation | None
    status: str
    robust_worst: float = math.nan

    @property
    def tace(self) -> float:
        """The chosen point's nominal TACE (nan where there is none or it diverged)."""
        return self.chosen.outcome.tace if self.chosen is not None else math.nan


def best_search(searches: list) -> Search:
    """The search a combination keeps from its independent searches (:attr:`Protocol.searches`), judged by
    what each search itself measured, never by the draws: a robust chosen point with the lowest nominal
    TACE; where no search found one, a not-robust point with the lowest worst case over the perturbations;
    where none found an admissible point, the first search's status. Ties go to the earlier search."""
    robust = [s for s in searches if s.status == "ok" and math.isfinite(s.tace)]
    if robust:
        return min(robust, key=lambda s: s.tace)
    fallback = [s for s in searches if s.chosen is not None]
    if fallback:
        return min(fallback, key=lambda s: s.chosen.worst if math.isfinite(s.chosen.worst) else math.inf)
    return searches[0]


def tune(data: dict, sections: dict, keys: tuple, machine: dict, noise_limit: float, from_time: float,
         protocol: Protocol, where: str = "tuning", optimiser=None, robust_floor: float = 0.0) -> Tuned:
    """Tune the gains ``keys`` of ``sections['/ccc']`` (see the module docstring) on ``data`` with the
    machine settings ``machine``; then check robustness, run the draws and the ideal machine.
    ``optimiser``: another search with :func:`minimise`'s signature (to check the tuning against it).
    ``robust_floor`` [m]: a point is also robust when its worst TACE over the perturbations is at most this
    (the benchmark gives the proposed method's worst with the paper's gains, :func:`worst_case`): the same
    robustness as the paper's own design is enough, where that design itself degrades by more than
    robust_factor (otherwise only points far worse than the paper's would pass, and their error is large
    enough to hide any degradation)."""
    ccc = sections["/ccc"]
    file_gains = {k: ccc[k] for k in keys}
    tuned = Tuned(file_gains=file_gains)
    limits = _limits(data, machine)

    def with_gains(gains: dict) -> dict:
        return dict(sections, **{"/ccc": section_with_gains(ccc, gains)})

    def measure_many(points: list) -> list:
        """An Evaluation per gains mapping, run as one batch where the classes allow; a point is refused
        before it runs where its linear loop is unstable or beyond the Ms bound."""
        out, runnable = [], []
        for gains in points:
            try:
                experiment = experiment_for(data, with_gains(gains), machine, where)
            except ConfigError as error:
                out.append(Evaluation(gains, Outcome(failure=f"refused: {error}"), 100.0, False))
                continue
            robustness = loop_robustness(experiment) if protocol.ms_limit else None
            if robustness is not None and not robustness[0] <= robustness[2]:
                ms, stable, allowed = robustness
                what = "its linear loop is unstable" if not stable else f"Ms {ms:.3g} over {allowed:.3g}"
                excess = 3.0 if not stable else math.log10(ms / allowed)
                out.append(Evaluation(gains, Outcome(failure=f"refused: {what}"), 50.0 + PENALTY * excess, False))
                continue
            runnable.append((len(out), experiment))
            out.append(None)
        outcomes = _outcomes([e for _, e in runnable], from_time, [limits] * len(runnable))
        for (i, _), outcome in zip(runnable, outcomes):
            out[i] = Evaluation(points[i], outcome, *_objective(outcome, noise_limit, protocol))
        return out

    def measure(gains: dict) -> Evaluation:
        return measure_many([gains])[0]

    checks = perturbations(data, protocol.perturbation)
    incumbent = []             # the robust point with the lowest TACE so far in this search (at most one)

    def check(candidate: Evaluation) -> bool:
        """Robustness: every +-perturbation run stable, with its TACE at most robust_factor x the candidate's
        nominal TACE or at most ``robust_floor``. Keeps the worst TACE on the candidate."""
        candidate.worst = worst_case(data, with_gains(candidate.gains), machine, from_time, protocol, where)
        tuned.robustness_runs += len(checks)
        if math.isnan(candidate.worst):
            candidate.worst = candidate.outcome.tace
        return candidate.worst <= max(protocol.robust_factor * candidate.outcome.tace, robust_floor)

    def judge(evaluation: Evaluation) -> None:
        """Robust: the incumbent; not: inadmissible, its objective paying for it."""
        if check(evaluation):
            incumbent[:] = [evaluation]
            return
        bound = max(protocol.robust_factor * evaluation.outcome.tace, robust_floor)
        excess = evaluation.worst / bound if bound > 0 else math.inf
        evaluation.admissible = False
        evaluation.objective += PENALTY * (min(math.log10(max(excess, 1.0)), 3.0) + 0.1)
        evaluation.outcome = dataclasses.replace(
            evaluation.outcome, failure=f"not robust: {evaluation.worst / evaluation.outcome.tace:.3g}x the nominal "
                                        f"TACE at +-{100 * protocol.perturbation:g}% of a plant parameter")

    def evaluate_many(points: list) -> list:
        """Points of the search, run together. An admissible point that beats the robust incumbent by more
        than robust_step (or any, while there is none) is checked for robustness at once (:func:`judge`), so
        the search turns away from gains that only work on the nominal plant; smaller gains wait for the
        end."""
        evaluations = measure_many(points)
        for evaluation in evaluations:
            tuned.evaluations.append(evaluation)
            if evaluation.admissible and (not incumbent or evaluation.outcome.tace
                                          < (1.0 - protocol.robust_step) * incumbent[0].outcome.tace):
                judge(evaluation)
        return evaluations

    def evaluate(gains: dict) -> Evaluation:
        return evaluate_many([gains])[0]

    anchor = anchors(ccc, keys)
    # the box of the log-scaled gains and the file's point in it, the same for every search
    low = [math.log10(anchor[k]) - protocol.decades for k in keys]
    high = [math.log10(anchor[k]) + protocol.decades for k in keys]
    x0 = [math.log10(_magnitude(ccc[k])) if _magnitude(ccc[k]) > 0 else math.log10(anchor[k]) - 1.0 for k in keys]

    def objective(x):
        return evaluate(_gains_from(x, keys, anchor, protocol.decades)).objective

    def objectives(xs):
        return [e.objective for e in evaluate_many([_gains_from(x, keys, anchor, protocol.decades) for x in xs])]
    objective.many = objectives

    def search(search_protocol: Protocol) -> Search:
        """One search from the file's gains (its seed: ``search_protocol.seed``) and the choice it ends with."""
        incumbent.clear()
        first = len(tuned.evaluations)
        evaluate({k: _magnitude(ccc[k]) for k in keys})             # the file's gains
        if keys:
            # a coarse scan first: every gain scaled together by each of Protocol.scan (a file's gains may sit
            # decades from where the loop acts), then quasi-random points over the whole box (a basin where one
            # gain is off or decades from the others); the search starts from the best of all of them
            values = {tuple(x0): tuned.evaluations[first].objective}
            starts = [[min(max(v + shift, lo), hi) for v, lo, hi in zip(x0, low, high)] for shift in protocol.scan]
            if protocol.design:
                from scipy.stats import qmc
                unit = qmc.Sobol(len(keys), scramble=True, seed=search_protocol.seed).random(protocol.design)
                starts += qmc.scale(unit, low, high).tolist()
            fresh = []
            for x in starts:
                if tuple(x) not in values and tuple(x) not in map(tuple, fresh):
                    fresh.append(x)
            fresh = fresh[:max(protocol.evaluations - 1 - (len(tuned.evaluations) - first), 0)]
            values.update(zip(map(tuple, fresh), objectives(fresh)))
            start = list(min(values, key=values.get))
            (optimiser or minimise)(objective, start, low, high,
                                    protocol.evaluations - (len(tuned.evaluations) - first), search_protocol)
        mine = tuned.evaluations[first:]
        # the admissible points not checked yet that beat the incumbent, best first
        waiting = sorted((e for e in mine if e.admissible and math.isnan(e.worst)
                          and (not incumbent or e.outcome.tace < incumbent[0].outcome.tace)), key=lambda e: e.outcome.tace)
        for evaluation in waiting[:protocol.final_checks]:
            judge(evaluation)
            if incumbent and incumbent[0] is evaluation:
                break
        if incumbent:
            chosen = incumbent[0]
            return Search(chosen, "ok", chosen.worst / chosen.outcome.tace)
        # no robust point in the search: the best stable point that met the other constraints, backed off
        # a quarter decade at a time (every gain together, toward more margin)
        near = sorted((e for e in mine if e.outcome.ok or e.outcome.failure.startswith("not robust")),
                      key=lambda e: e.objective)
        if not near or near[0].objective >= 50.0:
            failures = sorted({e.outcome.failure.split(":")[0] for e in mine if e.outcome.failure})
            noisy = [e.outcome.noise / noise_limit for e in mine if e.outcome.ok and noise_limit > 0]
            return Search(None, "no admissible gain: every point diverged or broke a constraint"
                          + (f" (least noise {min(noisy):.3g} x the bound)" if noisy else "")
                          + (f" ({'; '.join(failures)})" if failures else ""))
        best = near[0]
        tried = []
        for step in range(1, protocol.backoff + 1):
            candidate = measure({k: v * 10.0 ** (-0.25 * step) for k, v in best.gains.items()})
            tuned.robustness_runs += 1
            if candidate.admissible:
                tried.append(candidate)
                if check(candidate):
                    return Search(candidate, "ok", candidate.worst / candidate.outcome.tace)
        # the checked point whose worst case over the perturbations is the lowest
        checked = [e for e in mine + tried if math.isfinite(e.worst)]
        chosen = min(checked, key=lambda e: e.worst) if checked else best
        status = (f"not robust: no point of the search, nor the best backed off {protocol.backoff} times, "
                  f"stays within {protocol.robust_factor:g}x at +-{100 * protocol.perturbation:g}% of a "
                  f"plant parameter while meeting the other constraints (given: the point with the "
                  f"lowest worst case)")
        robust_worst = chosen.worst / chosen.outcome.tace if math.isfinite(chosen.worst) and chosen.outcome.tace > 0 \
            else math.nan
        if not chosen.outcome.ok:
            chosen = Evaluation(chosen.gains, measure(chosen.gains).outcome, chosen.objective, False, chosen.worst)
        return Search(chosen, status, robust_worst)

    searches = [search(dataclasses.replace(protocol, seed=protocol.seed + i)) for i in range(protocol.searches)]
    kept = best_search(searches)
    tuned.search, tuned.search_tace = searches.index(kept), [s.tace for s in searches]
    tuned.status, tuned.robust_worst = kept.status, kept.robust_worst
    if kept.chosen is None:
        return tuned
    chosen = kept.chosen
    tuned.gains, tuned.nominal = chosen.gains, chosen.outcome
    for key in keys:
        value = chosen.gains[key]
        if value == 0.0:
            tuned.at_bound.append(f"{key} off")
        elif math.log10(value) >= math.log10(anchor[key]) + protocol.decades - 0.05:
            tuned.at_bound.append(f"{key} at the upper bound")
    final = with_gains(chosen.gains)
    tuned.draws = run_outcomes(data, final, [dict(machine, **draw_settings(data, j, protocol.mismatch))
                                             for j in range(protocol.draws)], from_time, where)
    tuned.ideal = run_outcomes(data, final, [{}], from_time, where)[0]          # the file's machine as it is
    tuned.margins = worst_margins(experiment_margins(experiment_for(data, final, machine, where)))
    return tuned


# ------------------------------------------------------------------------------------------ figures


def interval(values) -> tuple:
    """(median, 2.5th percentile, 97.5th percentile) of the finite ``values`` (nan where there are none)."""
    values = np.asarray([v for v in values if v is not None and math.isfinite(v)], dtype=float)
    if not values.size:
        return math.nan, math.nan, math.nan
    return (float(np.median(values)), float(np.percentile(values, 2.5)), float(np.percentile(values, 97.5)))


def pareto_front(points) -> list:
    """The points (noise, tace, ...) that no other point beats in both noise and TACE, by noise."""
    points = sorted((p for p in points if math.isfinite(p[0]) and math.isfinite(p[1])), key=lambda p: (p[0], p[1]))
    front, best = [], math.inf
    for p in points:
        if p[1] < best:
            front.append(p)
            best = p[1]
    return front
