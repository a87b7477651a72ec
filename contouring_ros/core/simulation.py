"""In-process simulation with exactly the node graph's step semantics (DESIGN.md, "One control step").

Step k at t_k = k Ts: the plants hold their state at k; the interpolator gives the reference at k; the
estimator combines reference and positions; the contour controller turns the estimate into corrections;
each servo turns reference, state and correction into its command; each plant applies its command over
[t_k, t_k+1). The nodes call the same objects in the same order on the same float64 values, so the graph
reproduces this loop to floating-point identity.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .interpolation import reference

__all__ = ["ControlLoop", "SimulationResult", "step_time", "simulate"]


def step_time(k: int, sample_time: float) -> float:
    """t_k = k Ts: the one expression every node and the simulation use for a step's time."""
    return k * sample_time


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
    """

    curve: object
    schedule: object
    plants: list
    servos: list
    estimator: object
    controller: object
    sample_time: float
    n_steps: int


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


def simulate(loop: ControlLoop) -> SimulationResult:
    """Run ``loop`` for its n_steps and return every signal."""
    m, n = loop.n_steps, len(loop.plants)
    time = np.empty(m)
    theta, est_theta, est_signed = np.empty(m), np.empty(m), np.empty(m)
    ref_pos, ref_vel, ref_acc, positions, velocities, est_vector, corrections, commands = (
        np.empty((m, n)) for _ in range(8))
    curve, schedule, estimator, controller = loop.curve, loop.schedule, loop.estimator, loop.controller
    axes = list(zip(range(n), loop.plants, loop.servos))
    for k in range(m):
        t = step_time(k, loop.sample_time)
        for i, plant, _ in axes:
            positions[k, i], velocities[k, i] = plant.measure()
        position, velocity = positions[k].copy(), velocities[k].copy()
        ref = reference(curve, schedule, t)
        estimate = estimator.step(ref, position)
        correction = controller.step(estimate, ref, position, velocity)
        rp, rv, ra = ref.position, ref.velocity, ref.acceleration
        for i, plant, servo in axes:
            command = servo.step(rp[i], rv[i], ra[i], position[i], velocity[i], correction[i])
            commands[k, i] = command
            plant.step(commands[k, i], t)
        time[k], theta[k], est_theta[k], est_signed[k] = t, ref.theta, estimate.theta, estimate.signed
        ref_pos[k], ref_vel[k], ref_acc[k] = rp, rv, ra
        est_vector[k], corrections[k] = estimate.vector, correction
    return SimulationResult(time=time, theta=theta, reference_position=ref_pos, reference_velocity=ref_vel,
                            reference_acceleration=ref_acc, position=positions, velocity=velocities,
                            estimate_theta=est_theta, estimate_vector=est_vector, estimate_signed=est_signed,
                            correction=corrections, command=commands)
