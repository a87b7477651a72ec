"""In-process simulation with exactly the node graph's step semantics (docs/ARCHITECTURE.md, "One control step").

Step k at t_k = k Ts: the plants hold their state at k; the interpolator gives the reference at k; the
estimator combines reference and positions; the contour controller turns the estimate into corrections;
each servo turns reference, state and correction into its command; each plant applies its command over
[t_k, t_k+1). The nodes call the same objects in the same order on the same float64 values, so the graph
reproduces this loop to floating-point identity.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import Diverged
from .interpolation import reference, reference_ahead, step_time
from .progress import EVERY, add as count_steps

__all__ = ["ControlLoop", "SimulationResult", "step_time", "simulate", "divergence_bound", "path_bound", "first_divergence",
           "diverged_message",
           "DIVERGENCE_FACTOR"]

DIVERGENCE_FACTOR = 10.0     # a run has diverged once an axis is this many path sizes from its reference


@dataclass
class ControlLoop:
    """The core objects of one experiment, wired as the node graph wires them.

    Attributes
    ----------
    curve, schedule :
        The reference contour and its parameter schedule (the interpolator).
    plants, servos : list
        One per axis, in axis order.
    estimator, controller :
        Contour error estimator and cross-coupled contour controller.
    sample_time : float
        Ts [s].
    n_steps : int
        Number of control steps; step k runs at t_k = k Ts for k = 0 .. n_steps - 1.
    preview : int
        Steps of reference beyond step k that the servos and the controller read: each servo whose ``preview``
        is non-zero gets its axis' positions at steps k + 1 .. k + its preview through ``look_ahead`` before
        its step, a controller whose ``preview`` is non-zero every axis' (an array (preview, n))
        (:func:`~contouring_ros.core.interpolation.reference_ahead`; the interpolator node publishes them
        with the reference of step k).
    reference_table :
        A :class:`~contouring_ros.core.interpolation.ReferenceTable` of the curve, schedule and sample time,
        which runs along the same path share (the same numbers, computed once), or None. Not read while an
        in-position ``clock`` sets the reference's times.
    """

    curve: object
    schedule: object
    plants: list
    servos: list
    estimator: object
    controller: object
    sample_time: float
    n_steps: int
    divergence_factor: float = 10.0     # see simulate(); 0: never stop for divergence
    clock: object = None                # InPositionClock (exact stops wait for the axes), or None: t_k
    preview: int = 0                    # steps of reference beyond step k the servos read (reference_ahead)
    reference_table: object = None      # ReferenceTable of the path, shared by the runs along it, or None
    monitor: object = None              # Monitor (contour / following-error limits: core/monitoring.py), or None
    feed_control: object = None         # FeedControl (holds, resumes, monitoring's stop: core/feed_control.py)


@dataclass
class SimulationResult:
    """Per-step signals of a run; every array has n_steps rows.

    Attributes
    ----------
    time : (m,) [s]
    theta : (m,) reference curve parameter
    reference_position, reference_velocity, reference_acceleration : (m, n)
    position, velocity : (m, n) measured axis state at each step
    estimate_theta : (m,) estimated foot-point parameter
    estimate_vector : (m, n) estimated contour error vector [m]
    estimate_signed : (m,) estimated signed contour error [m]
    correction : (m, n) cross-coupled corrections [command units]
    command : (m, n) actuator commands [command units]
    """

    time: np.ndarray
    theta: np.ndarray
    reference_position: np.ndarray
    reference_velocity: np.ndarray
    reference_acceleration: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    estimate_theta: np.ndarray
    estimate_vector: np.ndarray
    estimate_signed: np.ndarray
    correction: np.ndarray
    command: np.ndarray


def divergence_bound(reference_positions, factor: float = DIVERGENCE_FACTOR) -> float:
    """How far [m] an axis may be from its reference before the run counts as diverged: ``factor`` times
    the size of the reference path (its largest extent along an axis), plus 1 mm; infinite for factor 0
    (then only a position that is not finite counts)."""
    if not factor:
        return math.inf
    points = np.asarray(reference_positions, dtype=float)
    size = float(np.max(np.ptp(points, axis=0))) if points.size else 0.0
    return factor * size + 1e-3


def path_bound(curve, schedule, factor: float = DIVERGENCE_FACTOR) -> float:
    """:func:`divergence_bound` of the whole reference path the schedule traverses."""
    theta = np.linspace(schedule.theta_start, schedule.theta_end, 257)
    return divergence_bound(curve.point(theta), factor)


def diverged_message(t: float, k: int, distance: float, bound: float) -> str:
    """``diverged at t = ... s (step k): <what>`` for an axis ``distance`` [m] from its reference."""
    what = "a position is not finite" if not np.isfinite(distance) else \
        f"an axis is {distance:.3g} m from its reference (bound {bound:.3g} m: divergence_factor x the path's size)"
    return f"diverged at t = {t:g} s (step {k}): {what}"


def first_divergence(time, position, reference_position, bound: float | None = None) -> tuple | None:
    """None for a run that stayed within bounds, else (k, ``diverged at t = ... s (step k): <what>``) for its
    first step k whose position is not finite or farther from the reference than ``bound`` (default:
    :func:`divergence_bound` of the reference)."""
    reference_position = np.asarray(reference_position, dtype=float)
    bound = divergence_bound(reference_position) if bound is None else bound
    with np.errstate(invalid="ignore", over="ignore"):
        far = np.max(np.abs(np.asarray(position, dtype=float) - reference_position), axis=1) \
            if len(reference_position) else np.zeros(0)
        bad = ~(far <= bound)
    if not bad.any():
        return None
    k = int(np.argmax(bad))
    return k, diverged_message(float(time[k]), k, float(far[k]), bound)


def _cut(result: SimulationResult, k: int) -> SimulationResult:
    return SimulationResult(**{name: value[:k] for name, value in vars(result).items()})


def _allocate(m: int, n: int) -> SimulationResult:
    """A result of ``m`` steps of ``n`` axes whose arrays are allocated, not yet written."""
    return SimulationResult(time=np.empty(m), theta=np.empty(m), reference_position=np.empty((m, n)),
                            reference_velocity=np.empty((m, n)), reference_acceleration=np.empty((m, n)),
                            position=np.empty((m, n)), velocity=np.empty((m, n)), estimate_theta=np.empty(m),
                            estimate_vector=np.empty((m, n)), estimate_signed=np.empty(m),
                            correction=np.empty((m, n)), command=np.empty((m, n)))


def _steps(m: int, progress: bool):
    """The step indices 0 .. m - 1, behind a progress bar on stderr with ``progress``."""
    if not progress:
        return range(m)
    from tqdm import tqdm
    return tqdm(range(m), unit="step", unit_scale=True, mininterval=0.5, leave=False)


def simulate(loop: ControlLoop, stop_on_divergence: bool = True, progress: bool = False) -> SimulationResult:
    """Run ``loop`` for its n_steps and return every signal (``progress``: a progress bar on stderr).

    Raises
    ------
    Diverged
        When an axis position stops being finite or leaves :func:`divergence_bound` of the path for the
        loop's ``divergence_factor`` (checked each step with ``stop_on_divergence``); its ``result`` holds
        the steps before.
    """
    m, n = loop.n_steps, len(loop.plants)
    bound = path_bound(loop.curve, loop.schedule, loop.divergence_factor) if stop_on_divergence else math.nan
    result = _allocate(m, n)
    time, theta, est_theta, est_signed = result.time, result.theta, result.estimate_theta, result.estimate_signed
    ref_pos, ref_vel, ref_acc = result.reference_position, result.reference_velocity, result.reference_acceleration
    positions, velocities, est_vector = result.position, result.velocity, result.estimate_vector
    corrections, commands = result.correction, result.command
    curve, schedule, estimator, controller = loop.curve, loop.schedule, loop.estimator, loop.controller
    axes = list(zip(range(n), loop.plants, loop.servos))
    clock, monitor, control = loop.clock, loop.monitor, loop.feed_control
    table = loop.reference_table if clock is None and control is None else None
    previewing = [(i, plant, servo) for i, plant, servo in axes if getattr(servo, "preview", 0)]
    controller_preview = getattr(controller, "preview", 0)
    for k in _steps(m, progress):
        if k % EVERY == EVERY - 1:
            count_steps(EVERY)
        t = step_time(k, loop.sample_time)
        for i, plant, _ in axes:
            positions[k, i], velocities[k, i] = plant.measure()
        position, velocity = positions[k].copy(), velocities[k].copy()
        if control is not None:       # holds, resumes, the stop after a breach, in-position checks
            seen = (positions[k - control.delay].copy(), velocities[k - control.delay].copy()) \
                if control.clock is not None and k >= control.delay else (None, None)
            ref_time, ref = math.nan, control.reference(k, *seen)
        else:
            if clock is None:
                ref_time = t
            else:         # the reference of step k sees the positions of step k - delay, as in the graph
                seen = (positions[k - clock.delay].copy(), velocities[k - clock.delay].copy()) \
                    if k >= clock.delay else (None, None)
                ref_time = clock.time(k, *seen)
            ref = table.at(k) if table is not None else reference(curve, schedule, ref_time)
        for i in range(n if stop_on_divergence else 0):
            distance = abs(position[i] - ref.position[i])
            if not distance <= bound:        # also when not finite
                raise Diverged(diverged_message(t, k, distance, bound), k, t, _cut(result, k))
        estimate = estimator.step(ref, position)
        if monitor is not None:
            monitor.check(k, estimate.vector, ref.position, position, ref.theta)
        if loop.preview:
            ahead = table.ahead(k, loop.preview) if table is not None else \
                reference_ahead(curve, schedule, k, ref_time, loop.preview, loop.sample_time, clock).position
            for i, _, servo in previewing:
                servo.look_ahead(tuple(ahead[:servo.preview, i]))
            if controller_preview:
                controller.look_ahead(ahead[:controller_preview])
        correction = controller.step(estimate, ref, position, velocity)
        rp, rv, ra = ref.position, ref.velocity, ref.acceleration
        # the servos and plants take Python floats, as the nodes do from their messages (the same values;
        # numpy's scalars cost more than their arithmetic)
        floats = zip(rp.tolist(), rv.tolist(), ra.tolist(), position.tolist(), velocity.tolist(),
                     correction.tolist() if correction.__class__ is np.ndarray else correction)
        for (i, plant, servo), (r, r_dot, r_ddot, p, v, c) in zip(axes, floats):
            command = servo.step(r, r_dot, r_ddot, p, v, c)
            commands[k, i] = command
            plant.step(command if command.__class__ is float else commands[k, i], t)
        time[k], theta[k], est_theta[k], est_signed[k] = t, ref.theta, estimate.theta, estimate.signed
        ref_pos[k], ref_vel[k], ref_acc[k] = rp, rv, ra
        est_vector[k], corrections[k] = estimate.vector, correction
    return result
