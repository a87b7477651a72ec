"""Disturbance inputs D(t) to an axis (paper 000 eq. 2: the disturbance adds to the actuator command).

A disturbance is sampled at t_k and held over the step (zero-order hold), like the command it adds to.
"""
from __future__ import annotations

import math

__all__ = ["NoDisturbance", "ConstantDisturbance", "SinusoidalDisturbance"]


class NoDisturbance:
    """D(t) = 0."""

    def __call__(self, t: float) -> float:
        return 0.0


class ConstantDisturbance:
    """D(t) = value: a constant load, in actuator command units."""

    def __init__(self, value: float):
        self.value = float(value)

    def __call__(self, t: float) -> float:
        return self.value


class SinusoidalDisturbance:
    """D(t) = offset + amplitude sin(2 pi frequency t + phase)."""

    def __init__(self, amplitude: float, frequency: float, phase: float = 0.0, offset: float = 0.0):
        self.amplitude = float(amplitude)
        self.frequency = float(frequency)
        self.phase = float(phase)
        self.offset = float(offset)

    def __call__(self, t: float) -> float:
        return self.offset + self.amplitude * math.sin(2.0 * math.pi * self.frequency * t + self.phase)
