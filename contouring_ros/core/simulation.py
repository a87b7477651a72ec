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
    arrays = {name: np.empty((m, n)) for name in (
        "reference_position", "reference_velocity", "reference_acceleration", "position", "velocity",
        "estimate_vector", "correction", "command")}
    for k in range(m):
        t = step_time(k, loop.sample_time)
        measured = [plant.measure() for plant in loop.plants]
        position = np.array([p for p, _ in measured])
        velocity = np.array([v for _, v in measured])
        ref = reference(loop.curve, loop.schedule, t)
        estimate = loop.estimator.step(ref, position)
        correction = loop.controller.step(estimate, ref, position, velocity)
        command = np.array([servo.step(ref.position[i], ref.velocity[i], ref.acceleration[i],
                                       position[i], velocity[i], correction[i])
                            for i, servo in enumerate(loop.servos)])
        for i, plant in enumerate(loop.plants):
            plant.step(command[i], t)
        time[k], theta[k] = t, ref.theta
        est_theta[k], est_signed[k] = estimate.theta, estimate.signed
        for name, value in (("reference_position", ref.position), ("reference_velocity", ref.velocity),
                            ("reference_acceleration", ref.acceleration), ("position", position),
                            ("velocity", velocity), ("estimate_vector", estimate.vector),
                            ("correction", correction), ("command", command)):
            arrays[name][k] = value
    return SimulationResult(time=time, theta=theta, estimate_theta=est_theta, estimate_signed=est_signed,
                            **arrays)
