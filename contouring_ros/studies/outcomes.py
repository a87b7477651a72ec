"""A combination's runs and their figures: the validated experiment of a file with sections and machine
settings applied, simulated in-process (one vectorised batch where the classes allow, a learning experiment's
passes together), each run's steady-state :class:`~contouring_ros.studies.tuning.Outcome` (TACE, noise
sensitivity, saturated share, effort), and the worst case over the robustness runs. The protocol:
:mod:`contouring_ros.studies.tuning`."""
from __future__ import annotations

import copy
import math

import numpy as np

from ..errors import ConfigError
from ..experiment.settings import apply_settings
from ..experiment.validate import experiment_from_data
from .learning import passes, simulate_last_passes
from .machine import actuator_limits, perturbations
from .sweep import score_one, simulate_experiments
from .tuning import Outcome, Protocol

__all__ = ["experiment_for", "experiment_outcomes", "run_outcomes", "worst_case"]


def experiment_for(data: dict, sections: dict, settings: dict, where: str):
    """The validated experiment of ``data`` (a parsed experiment file) with the node ``sections`` and the
    grid ``settings`` applied (ConfigError when refused)."""
    here = apply_settings(apply_settings(copy.deepcopy(data), sections), settings)
    return experiment_from_data(here, where)


def experiment_outcomes(experiments: list, from_time: float, limits: list) -> list:
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
    """A run's :class:`Outcome` from its loop and result: scored from ``from_time`` on, ``limits`` each axis'
    actuator limit (0: none)."""
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


def run_outcomes(data: dict, sections: dict | list, settings_list: list, from_time: float, where: str) -> list:
    """An :class:`Outcome` per settings mapping: :func:`experiment_for` each, simulated in-process (batched
    where the classes allow, :func:`experiment_outcomes`); one that cannot be built is refused, the others
    still run. ``sections``: the combination's sections, or a list of them, one per settings mapping (several
    combinations in one batch)."""
    every = sections if isinstance(sections, list) else [sections] * len(settings_list)
    out, experiments, places = [], [], []
    for settings, mine in zip(settings_list, every):
        try:
            experiments.append(experiment_for(data, mine, settings, where))
            places.append(len(out))
            out.append(None)
        except ConfigError as error:
            out.append(Outcome(failure=f"refused: {error}"))
    limits = [actuator_limits(data, settings_list[i]) for i in places]
    for i, outcome in zip(places, experiment_outcomes(experiments, from_time, limits)):
        out[i] = outcome
    return out


def worst_case(data: dict, sections: dict, machine: dict, from_time: float, protocol: Protocol, where: str) -> float:
    """The worst steady-state TACE [m] of ``sections`` on ``machine`` over the robustness runs
    (:func:`~contouring_ros.studies.machine.perturbations`); inf where one diverges."""
    runs = run_outcomes(data, sections, [dict(machine, **c) for c in perturbations(data, protocol.perturbation)],
                        from_time, where)
    return max((r.tace if r.ok else math.inf) for r in runs) if runs else math.nan
