"""Disturbance inputs D(t) to an axis (paper 000 eq. 2: the disturbance adds to the actuator command).

A disturbance is sampled at t_k and held over the step (zero-order hold), like the command it adds to.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["NoDisturbance", "ConstantDisturbance", "SinusoidalDisturbance", "RandomDisturbance"]


class NoDisturbance:
    """D(t) = 0."""

    #: steps elementwise on arrays with a leading batch axis (:mod:`contouring_ros.core.batch`)
    batchable = True

    def __call__(self, t: float) -> float:
        return 0.0


class ConstantDisturbance:
    """D(t) = value: a constant load, in actuator command units."""

    #: steps elementwise on arrays with a leading batch axis (:mod:`contouring_ros.core.batch`)
    batchable = True

    def __init__(self, value: float):
        self.value = float(value)

    def __call__(self, t: float) -> float:
        return self.value


class SinusoidalDisturbance:
    """D(t) = offset + amplitude sin(2 pi frequency t + phase)."""

    #: steps elementwise on arrays with a leading batch axis (:mod:`contouring_ros.core.batch`)
    batchable = True

    def __init__(self, amplitude: float, frequency: float, phase: float = 0.0, offset: float = 0.0):
        self.amplitude = float(amplitude)
        self.frequency = float(frequency)
        self.phase = float(phase)
        self.offset = float(offset)

    def __call__(self, t: float) -> float:
        angle = 2.0 * math.pi * self.frequency * t + self.phase
        return self.offset + self.amplitude * (np.sin(angle) if isinstance(angle, np.ndarray) else math.sin(angle))


class RandomDisturbance:
    """D(t) = offset + std * N(0, 1), a new Gaussian sample every step, reproducible from ``seed``.

    The sample of time t depends only on (seed, t in nanoseconds), never on how often or in which order
    D is called, so the node graph and the in-process simulation see the same sequence.
    """

    #: a batch (:mod:`contouring_ros.core.batch`) draws each member's sample from its own seed; numbers that
    #: differ across it are (B, 1) columns
    batchable = True

    def __init__(self, std: float, seed: int = 0, offset: float = 0.0):
        self.std, self.seed, self.offset = float(std), int(seed), float(offset)

    def __call__(self, t: float) -> float:
        key = int(round(t * 1e9))
        if np.ndim(self.seed):           # a batch of seeds (B, 1): one generator each, as alone
            samples = [np.random.default_rng([int(seed), key]).standard_normal() for seed in self.seed[:, 0]]
            return self.offset + self.std * np.array(samples)[:, None]
        if np.ndim(self.std) == 0 and self.std == 0.0:
            return self.offset
        return self.offset + self.std * float(np.random.default_rng([self.seed, key]).standard_normal())
