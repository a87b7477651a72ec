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

Search. Each method is searched in its physical tuning space (:func:`tuning_space`: its catalogue entry's
``tuning``, :mod:`contouring_ros.core.tuning_space`): loop bandwidths and corner frequencies in Hz below the
Nyquist frequency, damping ratios, weight ratios, each with a range a control engineer would accept; a
plugin that states none is searched over the log box of its raw gains. Every combination gets
:attr:`Protocol.searches` independent searches (search i: seed ``seed + i``; the first starts from the file's
gains, evaluated first, the others from uniform random points of the box), each IPOP-CMA-ES
(:func:`contouring_ros.studies.search.ipop_cmaes`: restarts with a doubled population, every population run as one
vectorised batch, robustness checks batched too) of at most :attr:`Protocol.evaluations` evaluations. The
row is *converged* when at least :attr:`Protocol.agree` searches end within :attr:`Protocol.agreement` of the
best nominal TACE (:func:`searches_agreement`); while it is not, as many more searches as the agreement
lacks run side by side (seeds continuing), up to :attr:`Protocol.max_searches`, the same cap for every
method. The best search is kept (:func:`best_search`); the draws run once, for its gains.

Constraints (the same for every method of a scenario, measured in simulation):

- stable: the run did not diverge;
- noise sensitivity: the RMS of the command's sample-to-sample change in the steady state (RMS over the
  axes) at most :attr:`Protocol.noise_factor` times the proposed method's with the paper's gains on the
  same machine and seed;
- saturation: at most :attr:`Protocol.saturation_share` of the steady-state steps with an axis' command
  at or beyond its limit;
- peak sensitivity, where the loop is linear (PID, PID + feedforward, ZPETC and cascade servos with a linear
  contour controller; :func:`loop_robustness`): the closed loop stable and Ms at most :data:`MS_LIMIT`
  (Åström & Hägglund's 1.4-2), or the drive's own Ms where its servo alone already exceeds that; a point
  beyond it is refused before it runs;
- robustness: with each plant parameter (gain, time constant, mass, damping) at plus and minus
  :attr:`Protocol.perturbation` on every axis, the run stays stable and its steady-state TACE within
  :attr:`Protocol.robust_factor` times the nominal one, or no worse than the proposed method's worst TACE
  there with the paper's gains (the same robustness as the paper's own design is enough: where that design
  itself degrades by more than the factor, a rule relative to a point's own error alone would pass only
  points far worse than the paper's, whose large error hides their degradation). Every point that could
  become its search's choice (its nominal objective below the search's best admissible one) is run at
  every perturbation (:meth:`Tuning.measure`), so a search chooses what it would were every point checked;
  a point that could not is left unchecked, its objective the nominal one. Where no point of a
  search is robust, the one with the lowest worst case is given, marked "not robust".

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

import control
import numpy as np

from ..experiment.build import build_controller, build_curve, build_plant, build_servo
from ..experiment.catalogue import CONTROLLERS, PLANTS, SERVOS
from ..experiment.validate import experiment_from_data
from ..experiment.schema import GLOBAL_SECTION
from ..core.margins import GainScaledLoops, axis_loop, coupled_loop, margins, quick_robustness
from ..core.servo import PIDServo
from ..core.tuning_space import Space, TuningContext, combine, gain_magnitude, log_box
from ..errors import ConfigError
from .learning import passes, simulate_last_passes
from .search import IPOPCMAES, Agreement, agreement, run_side_by_side
from .sweep import score_one, simulate_experiments
from ..experiment.settings import apply_settings

__all__ = ["REALISTIC", "SATURATION_MARGIN", "varied_parameters", "Protocol", "Outcome",
           "Evaluation", "Tuned", "gain_keys", "machine_settings", "perturbations", "draw_settings",
           "experiment_for", "fit_to_machine", "section_with_gains", "sections_with_gains", "tuning_space",
           "experiment_margins", "worst_margins", "loop_robustness", "MS_LIMIT", "run_outcomes", "worst_case",
           "Search", "best_search", "searches_agreement", "Tuning", "tune", "interval", "pareto_front"]

#: plant keys of the realistic machine (a key the scenario file sets is kept)
REALISTIC = {"encoder_resolution": 1e-7, "measurement_noise": 5e-8, "command_delay": 1,
             "velocity_measurement": "encoder"}
#: the actuator limit, where the paper states none: this times the proposed method's largest command
SATURATION_MARGIN = 2.0
MS_LIMIT = 2.0      # peak sensitivity a linear loop may reach (Åström & Hägglund: 1.4-2)
PENALTY = 10.0      # objective added per decade (log10) a constraint is exceeded by; diverged: 100


@dataclass(frozen=True)
class Protocol:
    """The tuning protocol: the same numbers for every method of a benchmark."""

    evaluations: int = 400         # evaluations per search (the file's gains included in the first)
    design: int = 48               # each search's first points: scrambled Sobol over the whole box, one batch
    popsize: int = 16              # the first CMA-ES run's population; each restart doubles it (IPOP)
    step: float = 0.25             # CMA-ES's first step [share of each coordinate's range]
    searches: int = 3              # independent searches per combination (seeds seed, seed + 1, ...)
    max_searches: int = 6          # ... more, side by side, while they do not agree, up to this many
    agreement: float = 0.05        # searches agree when they end within this share of the best nominal TACE
    agree: int = 3                 # ... and a row is converged when at least this many do
    decades: float = 8.0           # the log box of a plugin that states no space: each gain's span either side
    noise_factor: float = 2.0      # noise sensitivity at most this x the proposed method's (paper's gains)
    saturation_share: float = 0.01  # share of steady-state steps at the actuator limit, at most
    perturbation: float = 0.2      # robustness: each plant parameter x (1 +- this)
    robust_factor: float = 3.0     # ... with steady-state TACE at most this x the larger of the nominal and the floor
    ms_limit: bool = True          # refuse points whose linear loop has Ms over MS_LIMIT (see loop_robustness)
    draws: int = 8                 # noise seeds x model-mismatch draws of the interval
    mismatch: float = 0.1          # model mismatch of a draw: each plant parameter x U(1 - this, 1 + this)
    seed: int = 1                  # search i's seed is seed + i (its CMA-ES samples and, from search 1 on, its start)

    def describe(self) -> str:
        return (f"each method in its physical tuning space (bandwidths and corner frequencies in Hz, damping and "
                f"weight ratios; a plugin without one: each raw gain log-scaled over +-{self.decades:g} decades); "
                f"{self.searches} to {max(self.searches, self.max_searches)} independent searches per combination "
                f"(the first from the file's gains, the others from uniform random points), each "
                f"{self.design} scrambled-Sobol points over the box, then IPOP-CMA-ES from the best point "
                f"(population {self.popsize}, doubled at each restart; the searches' populations run as one "
                f"batch), at most {self.evaluations} evaluations in all; converged when {self.agree} searches end within "
                f"{100 * self.agreement:g}% of the best nominal TACE; noise sensitivity <= {self.noise_factor:g} "
                f"x the proposed method's; <= {100 * self.saturation_share:g}% of steps saturated; "
                f"{f'linear loops stable with Ms <= {MS_LIMIT:g}; ' if self.ms_limit else ''}robust: stable at "
                f"+-{100 * self.perturbation:g}% of each plant parameter with TACE <= {self.robust_factor:g} x "
                f"nominal, or no worse than the proposed method's worst there with the paper's gains; "
                f"{self.draws} draws (noise seed, +-{100 * self.mismatch:g}% model mismatch)")


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
    unit: list = field(default_factory=list)     # where in the search's unit box
    point: dict = field(default_factory=dict)    # the tuning space's values there
    search: int = 0                              # which search evaluated it


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
    search: int = 0                                    # which of the searches was kept
    search_tace: list = field(default_factory=list)    # each search's chosen nominal TACE [m] (nan: none)
    search_evaluations: list = field(default_factory=list)   # each search's evaluations
    agreement: object = None                           # search.Agreement of the searches
    point: dict = field(default_factory=dict)          # the kept gains in the tuning space's coordinates
    space: str = ""                                    # the tuning space, described

    @property
    def converged(self) -> bool:
        """Whether the searches agreed (:func:`contouring_ros.studies.search.agreement`)."""
        return bool(self.agreement is not None and self.agreement.converged)

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


def _set_gain(section: dict, key: str, magnitude: float) -> None:
    """The gain ``key`` of ``section`` set to ``magnitude`` (a per-axis list keeps its proportions; a list
    of zeros becomes ``magnitude`` on every axis)."""
    value = section.get(key, magnitude)
    if isinstance(value, list):
        top = gain_magnitude(value)
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


# ---------------------------------------------------------------------------------------- machines


def _plants(data: dict) -> dict:
    """'/x/plant' -> its parameters, for every axis of the file."""
    axes = data[GLOBAL_SECTION]["ros__parameters"]["axes"]
    return {f"/{a}/plant": data[f"/{a}/plant"]["ros__parameters"] for a in axes}


def machine_settings(data: dict, kind: str, peak_command: tuple = ()) -> dict:
    """Grid settings (see :mod:`contouring_ros.studies.sweep`) that put the file's plants on a machine ``kind``:
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
    (:func:`contouring_ros.studies.sweep.simulate_experiments`), the others one by one. A learning experiment (more
    than one pass, :mod:`contouring_ros.studies.learning`) runs every pass and is judged by its last: what the part
    is like once the correction has been learned; the learning experiments' passes run together, pass by
    pass (:func:`contouring_ros.studies.learning.simulate_last_passes`)."""
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
    """(objective, admissible): log10 of the TACE in um, plus :data:`PENALTY` per decade the noise bound is
    exceeded by and per unit share of steps saturated beyond the allowed share (continuous across each
    bound, so that a search can settle on an optimum that lies on it); 100 for a run that diverged."""
    if not outcome.ok or not math.isfinite(outcome.tace):
        return 100.0, False
    value = math.log10(max(outcome.tace, 1e-15) * 1e6)
    excess = 0.0
    if math.isfinite(noise_limit) and outcome.noise > noise_limit:
        excess += math.log10(outcome.noise / noise_limit)
    if outcome.saturated > protocol.saturation_share:
        excess += 10.0 * (outcome.saturated - protocol.saturation_share)
    admissible = (not math.isfinite(noise_limit) or outcome.noise <= noise_limit) \
        and outcome.saturated <= protocol.saturation_share
    return value + PENALTY * excess, admissible


def loop_robustness(experiment, servo_tuned: bool = False) -> tuple | None:
    """(Ms, stable, allowed Ms) of the least robust linear loop of an experiment, fast enough to ask at every
    point of a search (:func:`contouring_ros.core.margins.quick_robustness`); None when no loop is linear.
    The loop is each axis coupled with a linear contour controller (:func:`experiment_margins`'s "coupled");
    allowed is :data:`MS_LIMIT`, or the axis loop's own Ms where the drive's servo alone already exceeds it
    (a contour controller must then not make it worse), unless the servo's own gains are tuned
    (``servo_tuned``: then its loop is held to the bound too, and where the contour controller is not linear,
    the axis loop alone is the loop judged)."""
    worst = None
    for loops in _loops(experiment).values():
        loop = loops["coupled"] if loops["coupled"] is not None or not servo_tuned else loops["axis"]
        if loop is None:
            continue
        ms, stable = quick_robustness(loop)
        allowed = max(MS_LIMIT, quick_robustness(loops["axis"])[0]) \
            if loops["axis"] is not None and not servo_tuned else MS_LIMIT
        here = (ms if stable else math.inf, stable, allowed)
        if worst is None or here[0] / here[2] > worst[0] / worst[2]:
            worst = here
    return worst


def _scaled_loops(data: dict, sections: dict, machine: dict, where: str) -> GainScaledLoops | None:
    """The coupled loops of a combination whose contour controller is a linear PID, as its gains are scaled
    together (:class:`contouring_ros.core.margins.GainScaledLoops`): built from the loops with the controller's
    gains at 0 and with each gain alone (a per-axis list keeping its proportions); None where a loop is
    not linear or the controller has no kp, ki and kd."""
    ccc = sections.get("/ccc") or {}
    if not all(key in ccc for key in ("kp", "ki", "kd")):
        return None
    # each gain's loop at a scale comparable to the servo's own gains (a unit gain beside a servo's 1e7 would
    # be lost in the loop polynomials' rounding), then per unit of that gain
    servo = next((v for k, v in sections.items() if k.endswith("/servo")), {}) or {}
    scale = gain_magnitude(servo.get("kp", 0.0)) or gain_magnitude(ccc.get("kp", 0.0)) or 1.0
    sizes = {"kp": scale, "ki": scale * 2 * math.pi * 10.0, "kd": scale * 1e-3}
    try:
        zero = _loops(experiment_for(data, sections_with_gains(sections, {"kp": 0.0, "ki": 0.0, "kd": 0.0}), machine,
                                     where))
        unit = {g: _loops(experiment_for(data, sections_with_gains(sections, {k: (size if k == g else 0.0) for k in sizes}),
                                         machine, where)) for g, size in sizes.items()}
    except (ConfigError, ValueError):
        return None
    axes = []
    for axis, loops in zero.items():
        if loops["coupled"] is None or loops["axis"] is None or any(unit[g][axis]["coupled"] is None for g in sizes):
            return None
        allowed = max(MS_LIMIT, quick_robustness(loops["axis"])[0])
        axes.append((loops["coupled"], {g: (unit[g][axis]["coupled"], sizes[g]) for g in sizes}, allowed))
    return GainScaledLoops(axes, MS_LIMIT)


def _servo_loops(experiment) -> dict:
    """{axis: its loop alone as its servo's PID gains are scaled together
    (:class:`contouring_ros.core.margins.GainScaledLoops`, the loop zero without them)}: each gain's loop that
    of a PID servo with that gain alone (the servos whose PID this serves, the ZPETC's, run the same loop,
    :func:`contouring_ros.core.margins.axis_loop`), at the size of the servo's own kp; {} where an axis' loop
    is not linear."""
    ts = float(experiment.sample_time)
    out = {}
    for axis in experiment.axes:
        plant = build_plant(experiment, axis, 0.0, 0.0)
        size = gain_magnitude(experiment.servos[axis].get("kp", 0.0)) or 1.0
        sizes = {"kp": size, "ki": size * 2 * math.pi * 10.0, "kd": size * 1e-3}
        units = {}
        for gain, value in sizes.items():
            loop = axis_loop(plant, PIDServo(*(value if g == gain else 0.0 for g in sizes), ts), ts)
            if loop is None:
                return {}
            units[gain] = (loop, value)
        out[axis] = GainScaledLoops([(control.tf([0.0], [1.0], ts), units, MS_LIMIT, lambda gains, plant=plant: axis_loop(
            plant, PIDServo(gains["kp"], gains["ki"], gains["kd"], ts), ts))], MS_LIMIT)
    return out


def _tuned_servo(experiment):
    """The catalogue entry of the experiment's servo law where every axis has the same law and that law
    states a tuning space of its own (the ZPETC's PID), else None."""
    laws = {experiment.servos[a]["law"] for a in experiment.axes}
    entry = SERVOS.entry(laws.pop()) if len(laws) == 1 else None
    return entry if entry is not None and entry.tuning is not None else None


def tuning_space(data: dict, sections: dict, keys: tuple, protocol: Protocol, where: str = "tuning",
                 machine: dict | None = None) -> tuple:
    """(the space a combination is tuned in, the validated sections its file point is read from): its
    controller's catalogue ``tuning`` space (else the log box of its raw gains ``keys``,
    :func:`contouring_ros.core.tuning_space.log_box`; none without either), with the space of the servos
    added where their law states one (the ZPETC's PID). A linear PID contour controller is searched at a chosen
    Ms of its coupled loops on the ``machine`` (grid settings; :func:`_scaled_loops`), where the protocol
    bounds Ms and the servos' gains stay the file's; a servo law's PID that is tuned too (the ZPETC's) at a
    chosen Ms of each axis' own loop on the machine (:func:`_servo_loops`)."""
    experiment = experiment_for(data, sections, {}, where)
    axes = list(experiment.axes)
    responses = {}
    for a in axes:
        plant = experiment.plants[a]
        entry = PLANTS.entry(plant["model"])
        responses[a] = (lambda w, e=entry, s=plant: e.response(s, w)) if entry.response else None
    servo_entry = _tuned_servo(experiment)
    scaled = _scaled_loops(data, sections, machine or {}, where) if protocol.ms_limit and servo_entry is None else None
    servo_loops = _servo_loops(experiment_for(data, sections, machine or {}, where)) \
        if protocol.ms_limit and servo_entry is not None else {}
    context = TuningContext(float(experiment.sample_time), dict(experiment.plants), dict(experiment.servos), responses,
                            scaled, servo_loops)
    validated = {"/ccc": experiment.controller, **{f"/{a}/servo": experiment.servos[a] for a in axes}}
    entry = CONTROLLERS.entry(experiment.controller["type"])
    space = entry.tuning(experiment.controller, context) if entry.tuning else None
    if space is None and keys:
        space = log_box(experiment.controller, keys, protocol.decades)
    if servo_entry is not None:
        space = combine(space, servo_entry.tuning(experiment.servos[axes[0]], context))
    return space or Space((), lambda values: {}, lambda sections: {}, "none"), validated


def sections_with_gains(sections: dict, gains: dict) -> dict:
    """A copy of the node ``sections`` with raw ``gains`` set: a plain key on ``/ccc``, ``<axis>/servo.<key>``
    on that servo (a per-axis list keeps its proportions, :func:`_set_gain`)."""
    ccc = {k: v for k, v in gains.items() if "/" not in k}
    out = dict(sections, **{"/ccc": section_with_gains(sections["/ccc"], ccc)})
    for key, value in gains.items():
        if "/" in key:
            node, name = key.split(".", 1)
            out[f"/{node}"] = section_with_gains(out[f"/{node}"], {name: value})
    return out


@dataclass
class Search:
    """What one search of a :class:`Tuning` ends with: the chosen Evaluation (None: no admissible point), the
    status it gives the combination and the chosen point's worst TACE over the perturbations / its nominal."""

    chosen: Evaluation | None
    status: str
    robust_worst: float = math.nan
    evaluations: int = 0

    @property
    def tace(self) -> float:
        """The chosen point's nominal TACE (nan where there is none or it diverged)."""
        return self.chosen.outcome.tace if self.chosen is not None else math.nan

    @property
    def value(self) -> float:
        """What the searches of a row are compared by (:func:`agreement`): the nominal TACE of a robust
        choice; inf where the search found none."""
        return self.tace if self.status == "ok" and math.isfinite(self.tace) else math.inf


def best_search(searches: list) -> Search:
    """The search a combination keeps from its independent searches, judged by what each search itself
    measured, never by the draws: a robust chosen point with the lowest nominal TACE; where no search found
    one, a not-robust point with the lowest worst case over the perturbations; where none found an admissible
    point, the first search's status. Ties go to the earlier search."""
    robust = [s for s in searches if s.status == "ok" and math.isfinite(s.tace)]
    if robust:
        return min(robust, key=lambda s: s.tace)
    fallback = [s for s in searches if s.chosen is not None]
    if fallback:
        return min(fallback, key=lambda s: s.chosen.worst if math.isfinite(s.chosen.worst) else math.inf)
    return searches[0]


def searches_agreement(searches: list, protocol: Protocol) -> Agreement:
    """How far a row's searches agree (:func:`contouring_ros.studies.search.agreement` with the protocol's tolerance):
    on the robust choices' nominal TACE; where no search found a robust point, on the worst cases of their
    not-robust choices."""
    values = [s.value for s in searches]
    if not any(math.isfinite(v) for v in values):
        values = [s.chosen.worst if s.chosen is not None and math.isfinite(s.chosen.worst) else math.inf
                  for s in searches]
    return agreement(values, protocol.agreement, protocol.agree)


@dataclass
class _Run:
    """One search under way: its index and its evaluations."""

    index: int
    evaluations: list = field(default_factory=list)


class Tuning:
    """One combination's tuning (see the module docstring), as named steps: :meth:`measure` a batch of points,
    each on the nominal plant and at every robustness perturbation, in one vectorised batch; :meth:`evaluate`
    one round of the populations of searches side by side; :meth:`search` from given seeds and :meth:`choose`
    what each ends with; :meth:`run` searches until they agree (or the cap), then the draws."""

    def __init__(self, data: dict, sections: dict, keys: tuple, machine: dict, noise_limit: float, from_time: float,
                 protocol: Protocol, where: str = "tuning", robust_floor: float = 0.0, space: Space | None = None):
        self.data, self.sections, self.machine, self.where = data, sections, machine, where
        self.noise_limit, self.from_time, self.protocol, self.robust_floor = noise_limit, from_time, protocol, robust_floor
        self.space, self.validated = tuning_space(data, sections, keys, protocol, where, machine)
        self.servo_tuned = _tuned_servo(experiment_for(data, sections, {}, where)) is not None
        if space is not None:
            self.space = space
        self.checks = perturbations(data, protocol.perturbation)
        self.limits = [_limits(data, dict(machine, **change)) for change in [{}] + self.checks]
        self.tuned = Tuned(file_gains=({k: sections["/ccc"][k] for k in keys}), space=self.space.describe())

    # --- runs ----------------------------------------------------------------------------------------
    def with_gains(self, gains: dict) -> dict:
        return sections_with_gains(self.sections, gains)

    #: the robustness runs of a batch go in stages: each search's best STAGES[0] points that could become its
    #: choice, then the rest of those that still could (an admissible point among the first lowers the bar)
    STAGES = (2, math.inf)

    def measure(self, points: list, groups: list | None = None, best: dict | None = None) -> list:
        """An Evaluation per (unit point, values, gains): every point on the nominal plant in one batch, then,
        in :attr:`STAGES`, the points that could become their search's choice with each plant parameter at
        +-perturbation (:func:`perturbations`), each batch run as one where the classes allow. A point is
        refused unrun where its linear loop is unstable; beyond the Ms bound (:func:`loop_robustness`), not
        robust (its worst TACE over the perturbations above robust_factor x its nominal TACE and above the
        floor), too noisy or saturated it is inadmissible, its objective paying for it continuously across
        each bound (:func:`_objective`), so that a search can settle on an optimum on a bound.

        ``groups[i]``: which search point i belongs to (default: all one); ``best[group]``: that search's best
        admissible objective so far (default, or a search not named: none yet). A point whose nominal objective is
        not below its search's best admissible objective (the points of this batch checked before it
        included) cannot become that search's choice: an admissible point's objective is its nominal one,
        and the penalties only add. Its robustness runs are not made; its objective is the nominal one (a
        lower bound) and it is not admissible (:attr:`Evaluation.worst` nan). Every point that could be
        chosen is run at every perturbation, so a search chooses what it would were every point checked."""
        groups = [0] * len(points) if groups is None else groups
        best = {group: (best or {}).get(group, math.inf) for group in groups}
        out, nominal, owners, loops = [], [], [], {}
        for unit, values, gains in points:
            out.append(Evaluation(gains, Outcome(), 100.0, False, unit=unit, point=values))
            try:
                here = experiment_for(self.data, self.with_gains(gains), self.machine, self.where)
            except ConfigError as error:
                out[-1].outcome = Outcome(failure=f"refused: {error}")
                continue
            robustness = loop_robustness(here, self.servo_tuned) if self.protocol.ms_limit else None
            if robustness is not None and not robustness[1]:
                out[-1].outcome = Outcome(failure="refused: its linear loop is unstable")
                out[-1].objective = 50.0 + PENALTY * 3.0
                continue
            loops[len(out) - 1] = robustness
            nominal.append(here)
            owners.append(len(out) - 1)
        outcomes = dict(zip(owners, _outcomes(nominal, self.from_time, [self.limits[0]] * len(nominal))))
        for i, outcome in outcomes.items():
            self._judge(out[i], outcome, None, loops[i])
        waiting = sorted((i for i, o in outcomes.items() if o.ok and not out[i].outcome.failure.startswith("Ms")),
                         key=lambda i: out[i].objective)
        for stage in self.STAGES:
            counts, checked = {}, []
            for i in waiting:
                if out[i].objective < best[groups[i]] and counts.get(groups[i], 0) < stage:
                    counts[groups[i]] = counts.get(groups[i], 0) + 1
                    checked.append(i)
            if not checked:
                break
            perturbed = [experiment_for(self.data, self.with_gains(out[i].gains), dict(self.machine, **change),
                                        self.where) for i in checked for change in self.checks]
            runs = _outcomes(perturbed, self.from_time, self.limits[1:] * len(checked))
            self.tuned.robustness_runs += len(runs)
            n = len(self.checks)
            for k, i in enumerate(checked):
                self._judge(out[i], outcomes[i], runs[k * n:(k + 1) * n], loops[i])
                if out[i].admissible:
                    best[groups[i]] = min(best[groups[i]], out[i].objective)
            done = set(checked)
            waiting = [i for i in waiting if i not in done]
        return out

    def _judge(self, evaluation: Evaluation, nominal: Outcome, perturbed: list | None, ms: tuple | None) -> None:
        """The objective and admissibility of a point from its nominal run, its perturbed runs (None: not run,
        the point is then not admissible) and its linear loop's (Ms, stable, allowed Ms) (None: no linear
        loop)."""
        p = self.protocol
        objective, admissible = _objective(nominal, self.noise_limit, p)
        evaluation.outcome, evaluation.objective, evaluation.admissible = nominal, objective, admissible
        if not nominal.ok:
            return
        if ms is not None and ms[0] > ms[2]:
            evaluation.objective += PENALTY * math.log10(ms[0] / ms[2])
            evaluation.admissible = False
            evaluation.outcome = dataclasses.replace(nominal, failure=f"Ms {ms[0]:.3g} over {ms[2]:.3g}")
            return
        if perturbed is None:                    # robustness not checked (yet): not admissible
            evaluation.admissible = False
            return
        evaluation.worst = max((o.tace if o.ok else math.inf for o in perturbed), default=nominal.tace)
        bound = max(p.robust_factor * nominal.tace, self.robust_floor)
        if evaluation.worst > bound:
            evaluation.objective += PENALTY * min(math.log10(evaluation.worst / bound) if bound > 0 else 3.0, 3.0)
            evaluation.admissible = False
            evaluation.outcome = dataclasses.replace(
                nominal, failure=f"not robust: {evaluation.worst / nominal.tace:.3g}x the nominal TACE at "
                                 f"+-{100 * p.perturbation:g}% of a plant parameter")

    def evaluate(self, runs: list, asked: list) -> list:
        """One round of searches side by side: every search's points (``asked[i]`` of ``runs[i]``, unit points)
        measured in one batch (:meth:`measure`). Returns each search's objectives."""
        best = {run.index: min((e.objective for e in run.evaluations if e.admissible), default=math.inf)
                for run in runs}
        groups = [run.index for run, units in zip(runs, asked) for _ in units]
        evaluations = self.measure([(list(u), *self.space.decode(u)) for units in asked for u in units],
                                   groups, best)
        out, at = [], 0
        for run, units in zip(runs, asked):
            mine = evaluations[at:at + len(units)]
            at += len(units)
            for e in mine:
                e.search = run.index
            run.evaluations += mine
            out.append([e.objective for e in mine])
        self.tuned.evaluations += evaluations
        return out

    # --- searches --------------------------------------------------------------------------------------
    def start(self, index: int) -> list:
        """Search 0 starts from the file's gains, the others from a point drawn uniformly in the box (from
        their seed); each then goes from the best of its design's points where that is better."""
        if index == 0:
            return self.space.start(self.validated)
        rng = np.random.default_rng(10_000 + self.protocol.seed + index)
        return list(rng.uniform(0.0, 1.0, len(self.space.dimensions)))

    def search(self, indices: list, optimiser=None) -> list:
        """Searches ``indices`` (search i: seed protocol.seed + i) and the choice each ends with
        (:meth:`choose`). Search 0 evaluates the file's gains first. The searches run side by side, their
        populations in one batch (:func:`contouring_ros.studies.search.run_side_by_side`); another ``optimiser``
        runs them one at a time."""
        p = self.protocol
        runs = [_Run(i) for i in indices]
        for run in runs:
            if run.index == 0:
                self.evaluate([run], [[self.start(0)]])
        budget = {run.index: p.evaluations - len(run.evaluations) for run in runs}
        if optimiser is not None:
            for run in runs:
                optimiser(lambda units, run=run: self.evaluate([run], [units])[0], self.start(run.index),
                          budget[run.index], p.seed + run.index)
        else:
            searches = [IPOPCMAES(self.start(run.index), budget[run.index], p.seed + run.index, p.popsize, p.step,
                                  self.space.steps, math.log10(1.0 + p.agreement), p.design) for run in runs]
            for run, search in zip(runs, searches):
                if run.evaluations:                      # search 0: the file's gains, evaluated first
                    search.known_start(run.evaluations[0].objective)
            run_side_by_side(searches, lambda asked: self.evaluate(
                [run for run, search in zip(runs, searches) if not search.done], asked))
        return [self.choose(run.evaluations) for run in runs]

    def choose(self, mine: list) -> Search:
        """What a search ends with: its admissible point (robust, quiet, unsaturated) of lowest nominal TACE;
        where it has none, its point of lowest worst case among those that met every other constraint,
        marked not robust; else no admissible gain."""
        p = self.protocol
        admissible = [e for e in mine if e.admissible]
        if admissible:
            chosen = min(admissible, key=lambda e: e.outcome.tace)
            return Search(chosen, "ok", chosen.worst / chosen.outcome.tace, len(mine))
        fragile = [e for e in mine if e.outcome.failure.startswith("not robust")]
        if fragile:
            chosen = min(fragile, key=lambda e: e.worst)
            status = (f"not robust: no point of the search stays within {p.robust_factor:g}x at "
                      f"+-{100 * p.perturbation:g}% of a plant parameter while meeting the other constraints "
                      f"(given: the point with the lowest worst case)")
            return Search(chosen, status, chosen.worst / chosen.outcome.tace, len(mine))
        failures = sorted({e.outcome.failure.split(":")[0] for e in mine if e.outcome.failure})
        noisy = [e.outcome.noise / self.noise_limit for e in mine
                 if e.outcome.noise == e.outcome.noise and self.noise_limit > 0]
        return Search(None, "no admissible gain: every point diverged or broke a constraint"
                      + (f" (least noise {min(noisy):.3g} x the bound)" if noisy else "")
                      + (f" ({'; '.join(failures)})" if failures else ""), evaluations=len(mine))

    # --- the whole tuning ----------------------------------------------------------------------------
    def run(self, optimiser=None) -> Tuned:
        """protocol.searches searches, then more while they do not agree (:func:`searches_agreement`), up to
        protocol.max_searches; the best kept (:func:`best_search`); then the draws, the ideal machine and the
        margins of the kept gains."""
        p, tuned = self.protocol, self.tuned
        if not self.space.dimensions:                # nothing to tune: the file's gains, measured once
            searches = self.search([0], optimiser)
        else:
            searches = self.search(list(range(p.searches)), optimiser)
            cap = max(p.max_searches, p.searches)
            while len(searches) < cap:
                agreed = searches_agreement(searches, p)
                if agreed.converged:
                    break
                more = min(max(p.agree - agreed.agreed, 1), cap - len(searches))
                searches += self.search(list(range(len(searches), len(searches) + more)), optimiser)
        kept = best_search(searches)
        # nothing to tune: no search to agree with, the file's gains are the answer
        tuned.agreement = searches_agreement(searches, p) if self.space.dimensions else Agreement(1, 1, 1.0, True)
        tuned.search, tuned.search_tace = searches.index(kept), [s.tace for s in searches]
        tuned.search_evaluations = [s.evaluations for s in searches]
        tuned.status, tuned.robust_worst = kept.status, kept.robust_worst
        if kept.chosen is None:
            return tuned
        chosen = kept.chosen
        tuned.gains, tuned.nominal, tuned.point = chosen.gains, chosen.outcome, chosen.point
        tuned.at_bound = self.space.at_bound(chosen.unit)
        return self._finish(chosen.gains)

    def _finish(self, gains: dict) -> Tuned:
        tuned, p = self.tuned, self.protocol
        final = self.with_gains(gains)
        tuned.draws = run_outcomes(self.data, final, [dict(self.machine, **draw_settings(self.data, j, p.mismatch))
                                                      for j in range(p.draws)], self.from_time, self.where)
        tuned.ideal = run_outcomes(self.data, final, [{}], self.from_time, self.where)[0]   # the file's machine
        tuned.margins = worst_margins(experiment_margins(experiment_for(self.data, final, self.machine, self.where)))
        return tuned


def tune(data: dict, sections: dict, keys: tuple, machine: dict, noise_limit: float, from_time: float,
         protocol: Protocol, where: str = "tuning", optimiser=None, robust_floor: float = 0.0,
         space: Space | None = None) -> Tuned:
    """Tune the combination ``sections`` (see the module docstring and :class:`Tuning`) on ``data`` with the
    machine settings ``machine``; then run the draws and the ideal machine. ``keys``: the controller's raw
    gains (its file gains in the report; the log box of a plugin without a space). ``optimiser``: another
    search over the unit box, ``optimiser(objective_many, start, budget, seed)``, to check the tuning against
    it. ``space``: another space (e.g. :func:`contouring_ros.core.tuning_space.log_box` of the raw gains).
    ``robust_floor`` [m]: a point is also robust when its worst TACE over the perturbations is at most this
    (the benchmark gives the proposed method's worst with the paper's gains, :func:`worst_case`): the same
    robustness as the paper's own design is enough, where that design itself degrades by more than
    robust_factor (otherwise only points far worse than the paper's would pass, and their error is large
    enough to hide any degradation)."""
    return Tuning(data, sections, keys, machine, noise_limit, from_time, protocol, where, robust_floor, space).run(optimiser)


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
