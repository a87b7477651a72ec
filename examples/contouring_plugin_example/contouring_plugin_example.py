"""A contour error estimator in one file: contouring_ros finds it through the entry point group
``contouring_ros.estimators`` (see pyproject.toml), validates its section against ``params``, and builds
it with its section's keys and, by name, the experiment's ``curve`` (other names it may ask for:
``schedule``, ``sample_time``, ``axes``, ``n_axes``, ``experiment``).

The estimate: a fixed number of Newton steps on the foot-point condition (R(theta) - P) . R'(theta) = 0,
started from the reference point's parameter each step (no state carried between steps).
"""
from __future__ import annotations

import math

from contouring_ros.experiment.schema import Param
from contouring_ros.core.estimators import ContourEstimate
from contouring_ros.core.geometry import signed_error


class TwoStepNewtonEstimator:
    """``steps`` Newton steps (default 2) from theta_r towards the nearest foot point."""

    params = {"steps": Param("int", 2, "positive", help="Newton steps per control step", bounds=(1, 50))}

    def __init__(self, curve, steps: int = 2):
        self.curve = curve
        self.steps = int(steps)

    def step(self, reference, position) -> ContourEstimate:
        theta = float(reference.theta)
        for _ in range(self.steps):
            point, first, second = self.curve.derivatives(theta, order=2)
            error = point - position
            slope = float(first @ first + error @ second)
            if not slope > 0.0:          # not a minimum of the distance here: keep the last parameter
                break
            theta -= float(error @ first) / slope
        point, first = self.curve.derivatives(theta, order=1)
        vector = point - position
        tangent = first / math.sqrt(float(first @ first))
        return ContourEstimate(theta=theta, vector=vector, signed=float(signed_error(vector, tangent)))
