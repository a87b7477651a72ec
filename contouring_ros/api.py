"""The Python API: experiments, runs, bags, scores and sweeps without the command line (and without ROS).

    import contouring_ros as cr

    experiment = cr.load_experiment("paper000_b_ismc_h50_newton")   # a file, or a scenario of config/
    run = cr.simulate(experiment, {"ccc.kp": 2.0})                  # settings as sweep grid keys
    run.scores().mce, run.scores(from_time=0.3).tace                # metres; steady state from 0.3 s
    run.result.position, run.exact_contour_error()                  # per-step arrays (m,) / (m, n)
    table = run.table()                                             # column name -> array, as `export`
    bag = cr.read_bag("bags/run.mcap")                              # a recorded run, the same Run interface
    rows = cr.sweep_grid(experiment, {"ccc.kp": [0.5, 1, 2]}, from_time=0.3)

A diverging simulation raises :class:`contouring_ros.errors.Diverged` (its ``result`` holds the steps before);
bags of diverged runs are read up to the step before, with a warning in ``Run.warnings``.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .experiment.build import build_loop
from .experiment.catalogue.curves import program_warnings
from .experiment.files import load_experiment as _load_experiment
from .experiment.model import Experiment
from .experiment.ros_yaml import read_yaml
from .experiment.validate import experiment_from_data
from .core.geometry import ExactContourError
from .core.simulation import simulate as _simulate_loop
from .errors import ConfigError
from .experiment.scenarios import experiment_path
from .records.export import run_table
from .records.scoring import check_experiment_matches, curve_of, read_run, score_run
from .studies.learning import pass_experiment
from .studies.learning import simulate_passes as run_passes_in_process
from .studies.sweep import run_sweep
from .experiment.settings import apply_settings, name_settings

__all__ = ["Run", "load_experiment", "simulate", "simulate_passes", "read_bag", "sweep_grid"]


@dataclass
class Run:
    """One run, simulated or read from a bag.

    Attributes
    ----------
    experiment : Experiment
        The validated experiment (``experiment.text`` is its YAML).
    result : SimulationResult
        Per-step arrays: time, theta, reference_position/velocity/acceleration, position, velocity,
        estimate_theta, estimate_vector, estimate_signed, correction, command (SI units).
    curve : Curve
        The reference contour.
    warnings : list of str
        What a bag reader had to make do with; for a simulation, the setup words its part program read.
    loop : ControlLoop or None
        A simulation's core objects after the run (e.g. ``loop.controller.solve_times``, an MPCC's solve
        time of each step); None for a recorded run.
    """

    experiment: object
    result: object
    curve: object
    warnings: list = field(default_factory=list)
    loop: object = None

    @property
    def axes(self) -> list:
        return list(self.experiment.axes)

    def scores(self, from_time: float = 0.0):
        """The run's :class:`~contouring_ros.core.metrics.Scores` (lengths in metres), of the samples at
        t >= ``from_time`` when given (on a tool path, of the steps of its motion:
        :func:`contouring_ros.records.scoring.score_run`)."""
        return score_run(self.curve, self.result, from_time, self.experiment)

    def exact_contour_error(self) -> np.ndarray:
        """Distance [m] from each step's position to the whole reference curve."""
        return ExactContourError(self.curve)(self.result.position, near=self.result.theta).distance

    def table(self) -> dict:
        """Column name (with unit and axis) -> per-step array, the columns of ``contouring-ros export``."""
        return run_table(self.result, self.axes, self.curve)


def load_experiment(experiment):
    """A validated Experiment from a path or a scenario name of config/ (an Experiment is returned as is)."""
    if isinstance(experiment, Experiment):
        return experiment
    return _load_experiment(experiment_path(str(experiment)))


def _with_settings(experiment, settings: dict | None):
    """The experiment with ``settings`` applied and named after them (``<name>_ccc.kp-2.0``); its ``text`` is the
    changed file (so a bag keeps it)."""
    if not settings:
        return experiment
    import copy

    import yaml
    data = name_settings(apply_settings(copy.deepcopy(read_yaml(experiment.text, experiment.name)), settings),
                         settings, experiment.name)
    try:
        return experiment_from_data(data, f"{experiment.name} with {settings}",
                                    text=yaml.safe_dump(data, sort_keys=False))
    except ConfigError as error:
        raise ConfigError(f"settings {settings}: {error}") from None


def simulate(experiment, settings: dict | None = None) -> Run:
    """Simulate an experiment in-process (the node graph gives the same numbers), with ``settings`` applied
    first (grid keys as in sweeps, e.g. {"ccc.kp": 2.0, "x/servo.a": 10}, or {"/ccc": {"type": "none"}}).
    A learning experiment (ILC with ``passes`` > 1) runs its first pass here: :func:`simulate_passes` runs
    them all."""
    experiment = _with_settings(load_experiment(experiment), settings)
    loop = build_loop(experiment)
    return Run(experiment, _simulate_loop(loop), loop.curve, program_warnings(loop.curve), loop)


def simulate_passes(experiment, settings: dict | None = None) -> list:
    """A :class:`Run` per pass of a learning experiment (ILC: each pass plays back the correction learned
    from the one before, and meets noise of its own; :mod:`contouring_ros.studies.learning`), in order; one Run
    for any other experiment."""
    experiment = _with_settings(load_experiment(experiment), settings)
    return [Run(pass_experiment(experiment, j), result, loop.curve, program_warnings(loop.curve), loop)
            for j, (loop, result) in enumerate(run_passes_in_process(experiment), 1)]


def read_bag(path, experiment=None) -> Run:
    """A recorded run from its bag (the experiment stored in it, or ``experiment`` for a bag without one)."""
    given = load_experiment(experiment) if experiment is not None else None
    recorded = read_run(Path(path), experiment_text=given.text if given is not None else None, parsed=given)
    curve = curve_of(recorded)
    if given is not None:
        check_experiment_matches(recorded, curve, path)
    return Run(replace(recorded.require_experiment(), path=str(path)), recorded.result, curve, recorded.warnings)


def sweep_grid(experiment, grid: dict, from_time: float = 0.0, workers: int | None = None) -> list:
    """Every combination of ``grid`` (grid key -> values), ranked by MCE then TACE; each row has
    ``settings``, ``scores`` (None for a diverged run) and ``failure``."""
    return run_sweep(load_experiment(experiment).text, grid, workers, from_time=from_time)
