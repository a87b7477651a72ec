"""What a study's figures are summed up by: the median of a figure over a tuning's draws with its 2.5-97.5
percentile interval, and the Pareto front of error against noise sensitivity. The protocol:
:mod:`contouring_ros.studies.tuning`."""
from __future__ import annotations

import math

import numpy as np

__all__ = ["interval", "pareto_front"]


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
