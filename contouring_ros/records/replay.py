"""Estimator replay: contour error estimators run again over the reference and positions a bag recorded, each
measured against the exact contour error of the run.

Nothing here needs ROS: the run is a :class:`contouring_ros.records.bag.RecordedRun` read from a bag.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from tqdm import tqdm

from .bag import RecordedRun
from ..experiment.build import build_estimator
from ..experiment.catalogue import ESTIMATORS
from ..experiment.validate import validate_section
from ..core.geometry import ExactContourError
from ..core.interpolation import Reference
from ..errors import ConfigError
from .scoring import curve_of

__all__ = ["parse_estimator_spec", "EstimatorReplay", "replay_estimators"]


def parse_estimator_spec(spec: str) -> dict:
    """'newton:k_prime=800,tolerance=1e-10' -> {'type': 'newton', 'k_prime': 800.0, 'tolerance': 1e-10}."""
    name, _, options = spec.partition(":")
    section = {"type": name}
    for item in filter(None, options.split(",")):
        key, sep, value = item.partition("=")
        if not sep:
            raise ConfigError(f"--estimator {spec}: expected key=value, got {item!r}")
        try:
            section[key] = int(value)
        except ValueError:
            try:
                section[key] = float(value)
            except ValueError:
                section[key] = value
    integer_keys = {k for k, p in (ESTIMATORS[name] if name in ESTIMATORS else {}).items() if p.kind == "int"}
    return {k: (float(v) if isinstance(v, int) and k not in integer_keys else v) for k, v in section.items()}


@dataclass
class EstimatorReplay:
    """How one estimator tracks the exact contour error over a recorded run (lengths in metres)."""

    name: str
    estimate: np.ndarray          # |estimate| per step
    deviation_max: float
    deviation_rms: float


def replay_estimators(run: RecordedRun, specs: list, progress: bool = False) -> tuple[np.ndarray, list]:
    """Run each estimator of ``specs`` over the recorded reference and positions (a spec of the recorded
    estimator's type changes only the keys it names of the recorded section).

    Returns the exact contour error per step and, first for the recorded estimate and then for each spec,
    an :class:`EstimatorReplay`.
    """
    experiment = run.require_experiment()
    curve = curve_of(run)
    result = run.result
    exact = ExactContourError(curve)(result.position, near=result.theta).distance
    recorded = np.linalg.norm(result.estimate_vector, axis=1)
    replays = [_replay("recorded (" + experiment.estimator.get("type", "?") + ")", recorded, exact)]
    n = len(run.axes)
    for spec in specs:
        # of the recorded estimator's type, the recorded section with the spec's keys changed
        # (newton:k_prime=800 on a Newton run keeps its c_prime); of another type, the spec alone
        recorded_keys = {k: v for k, v in experiment.estimator.items() if v is not None}    # None: left to default
        given = {**recorded_keys, **spec} if spec["type"] == experiment.estimator.get("type") else spec
        # the estimator registry (built-in and plugin types alike): its keys, its constraints, its factory
        section = validate_section("--estimator", spec["type"], ESTIMATORS, given, experiment.axes)
        estimator = build_estimator(_with_estimator(experiment, section), curve)
        norms = np.empty(len(result.time))
        for k in tqdm(range(len(result.time)), desc=f"replaying {spec['type']}", disable=not progress,
                      leave=False, mininterval=0.5):
            ref = Reference(theta=result.theta[k], theta_dot=0.0, theta_ddot=0.0,
                            position=result.reference_position[k, :n], velocity=result.reference_velocity[k, :n],
                            acceleration=result.reference_acceleration[k, :n])
            norms[k] = np.linalg.norm(estimator.step(ref, result.position[k]).vector)
        label = spec["type"] + "".join(f" {k}={v:g}" if isinstance(v, float) else f" {k}={v}"
                                       for k, v in spec.items() if k != "type")
        replays.append(_replay(label, norms, exact))
    return exact, replays


def _with_estimator(experiment, section):
    return replace(experiment, estimator=section)


def _replay(name, estimate, exact) -> EstimatorReplay:
    deviation = np.abs(estimate - exact)
    return EstimatorReplay(name, estimate, float(deviation.max()), float(np.sqrt(np.mean(deviation ** 2))))
