"""Jerk-limited changes of speed in closed form: the time and distance of an S-curve from one speed to
another starting and ending at zero acceleration, and the highest speed one can reach within a distance (the
look-ahead's passes, :mod:`.feed_planning` and :mod:`.lookahead`)."""
from __future__ import annotations

import math

__all__ = ["SPARE", "reach", "scurve_distance", "scurve_time"]

#: a span's profile is planned over this fraction of its length less, so that none overshoots its end
SPARE = 1e-9


def scurve_time(dv: float, acceleration: float, jerk: float) -> float:
    """Shortest time of a jerk-limited change of speed by ``dv`` starting and ending at zero acceleration.

    The classic seven-phase S-curve (e.g. Biagiotti and Melchiorri, "Trajectory Planning for Automatic
    Machines and Robots", Springer 2008, section 3.4): with A^2 / J <= dv the acceleration ramps up in A / J,
    holds at A, ramps down: T = dv / A + A / J; otherwise it never reaches A: T = 2 sqrt(dv / J).
    """
    dv = abs(dv)
    if dv * jerk >= acceleration * acceleration:
        return dv / acceleration + acceleration / jerk
    return 2.0 * math.sqrt(dv / jerk)


def scurve_distance(v0: float, v1: float, acceleration: float, jerk: float) -> float:
    """Distance covered by that change of speed from v0 to v1: the acceleration profile is symmetric in
    time, so the mean speed is (v0 + v1) / 2."""
    return 0.5 * (v0 + v1) * scurve_time(v1 - v0, acceleration, jerk)


def reach(v0: float, length: float, cap: float, acceleration: float, jerk: float) -> float:
    """The highest speed (at most ``cap``) a jerk-limited profile can reach from ``v0`` within ``length``.

    Closed form: the speed change dv covers D = (2 v0 + dv) / 2 T(dv) (:func:`scurve_distance`). Without
    reaching the acceleration bound (dv <= A^2 / J) T = 2 sqrt(dv / J), so x = sqrt(dv) solves the depressed
    cubic x^3 + 2 v0 x - D sqrt(J) = 0, whose one real root is 2 sqrt(p / 3) sinh(asinh(3 q / (2 p)
    sqrt(3 / p)) / 3) with p = 2 v0, q = D sqrt(J) (the hyperbolic form of Cardano's formula); beyond it
    T = dv / A + A / J and dv solves the quadratic dv^2 / A + dv (2 v0 / A + A / J) + 2 v0 A / J - 2 D = 0.
    """
    if cap <= v0 or scurve_distance(v0, cap, acceleration, jerk) <= length:
        return cap
    p, q = 2.0 * v0, length * math.sqrt(jerk)
    if p > 0.0:
        x = 2.0 * math.sqrt(p / 3.0) * math.sinh(math.asinh(1.5 * q / p * math.sqrt(3.0 / p)) / 3.0)
    else:
        x = q ** (1.0 / 3.0)
    dv = x * x
    if dv * jerk > acceleration * acceleration:
        a, b, c = 1.0 / acceleration, p / acceleration + acceleration / jerk, p * acceleration / jerk - 2.0 * length
        dv = (-b + math.sqrt(b * b - 4.0 * a * c)) / (2.0 * a)
    return min(v0 + dv, cap)
