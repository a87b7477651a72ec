"""The linear loops of a combination and their robustness: each axis' loop alone and coupled with a linear
contour controller (:mod:`contouring_ros.core.margins`), their gain and phase margins and peak sensitivity Ms,
the least robust loop's Ms against :data:`~contouring_ros.studies.tuning.MS_LIMIT`, and the loops as a linear
PID's gains are scaled together (the coordinates a search chooses Ms in). The protocol:
:mod:`contouring_ros.studies.tuning`."""
from __future__ import annotations

import functools
import math

import control

from ..core.margins import GainScaledLoops, axis_loop, coupled_loop, margins, quick_robustness
from ..core.servo import PIDServo
from ..core.tuning_space import gain_magnitude
from ..errors import ConfigError
from ..experiment.build import build_controller, build_curve, build_path, build_plant, build_servo, shares_path
from .gains import sections_with_gains
from .outcomes import experiment_for
from .tuning import MS_LIMIT

__all__ = ["linear_loops", "experiment_margins", "worst_margins", "loop_robustness", "scaled_loops", "servo_loops"]


def linear_loops(experiment) -> dict:
    """{axis: {"axis": L(z) | None, "coupled": L(z) | None}}: each axis' loop alone
    (:func:`contouring_ros.core.margins.axis_loop`) and with the experiment's contour controller
    (:func:`~contouring_ros.core.margins.coupled_loop`: each axis as if the others were identical to it, on
    a straight line); None where the law is not linear time-invariant feedback."""
    ts = float(experiment.sample_time)
    curve, schedule = build_path(experiment)[:2] if shares_path(experiment.curve, experiment.schedule) else \
        (build_curve(experiment), None)         # a tool path's feed plan only where the controller asks for it
    controller = build_controller(experiment, curve, schedule)
    out = {}
    for axis in experiment.axes:
        plant = build_plant(experiment, axis, 0.0, 0.0)
        servo = build_servo(experiment, axis, 0.0, 0.0, 0.0)
        out[axis] = {"axis": axis_loop(plant, servo, ts), "coupled": coupled_loop(plant, servo, controller, ts)}
    return out


def experiment_margins(experiment) -> dict:
    """The margins of every axis of an experiment: {axis: {"axis": LoopMargins | None, "coupled": ...}} of
    the loops of :func:`linear_loops`."""
    ts = float(experiment.sample_time)
    return {axis: {name: None if loop is None else margins(loop, ts) for name, loop in loops.items()}
            for axis, loops in linear_loops(experiment).items()}


def worst_margins(per_axis: dict):
    """The axis loop with the highest Ms among the coupled loops (else the axis loops) of
    :func:`experiment_margins`, or None when no loop is linear."""
    loops = [m["coupled"] for m in per_axis.values() if m["coupled"] is not None] or \
        [m["axis"] for m in per_axis.values() if m["axis"] is not None]
    return max(loops, key=lambda m: m.ms) if loops else None


def loop_robustness(experiment, servo_tuned: bool = False) -> tuple | None:
    """(Ms, stable, allowed Ms) of the least robust linear loop of an experiment, fast enough to ask at every
    point of a search (:func:`contouring_ros.core.margins.quick_robustness`); None when no loop is linear.
    The loop is each axis coupled with a linear contour controller (:func:`experiment_margins`'s "coupled");
    allowed is :data:`MS_LIMIT`, or the axis loop's own Ms where the drive's servo alone already exceeds it
    (a contour controller must then not make it worse), unless the servo's own gains are tuned
    (``servo_tuned``: then its loop is held to the bound too, and where the contour controller is not linear,
    the axis loop alone is the loop judged)."""
    worst = None
    for loops in linear_loops(experiment).values():
        loop = loops["coupled"] if loops["coupled"] is not None or not servo_tuned else loops["axis"]
        if loop is None:
            continue
        ms, stable = quick_robustness(loop)
        allowed = max(MS_LIMIT, quick_robustness(loops["axis"])[0]) \
            if loops["axis"] is not None and not servo_tuned else MS_LIMIT
        here = (ms if stable else math.inf, stable, allowed)
        if worst is None or here[0] / here[2] > worst[0] / worst[2]:
            worst = here
    return worst


def _loops_with(data: dict, sections: dict, gains: dict, machine: dict, where: str) -> dict:
    """The :func:`linear_loops` of the combination ``sections`` with the contour controller's ``gains`` set, on
    the ``machine`` (grid settings)."""
    return linear_loops(experiment_for(data, sections_with_gains(sections, gains), machine, where))


def scaled_loops(data: dict, sections: dict, machine: dict, where: str) -> GainScaledLoops | None:
    """The coupled loops of a combination whose contour controller is a linear PID, as its gains are scaled
    together (:class:`contouring_ros.core.margins.GainScaledLoops`): built from the loops with the controller's
    gains at 0 and with each gain alone (a per-axis list keeping its proportions); None where a loop is
    not linear or the controller has no kp, ki and kd."""
    ccc = sections.get("/ccc") or {}
    if not all(key in ccc for key in ("kp", "ki", "kd")):
        return None
    # each gain's loop at a scale comparable to the servo's own gains (a unit gain beside a servo's 1e7 would
    # be lost in the loop polynomials' rounding), then per unit of that gain
    servo = next((v for k, v in sections.items() if k.endswith("/servo")), {}) or {}
    scale = gain_magnitude(servo.get("kp", 0.0)) or gain_magnitude(ccc.get("kp", 0.0)) or 1.0
    sizes = {"kp": scale, "ki": scale * 2 * math.pi * 10.0, "kd": scale * 1e-3}
    try:
        zero = _loops_with(data, sections, {"kp": 0.0, "ki": 0.0, "kd": 0.0}, machine, where)
        unit = {g: _loops_with(data, sections, {k: (size if k == g else 0.0) for k in sizes}, machine, where)
                for g, size in sizes.items()}
    except (ConfigError, ValueError):
        return None

    @functools.lru_cache(maxsize=32)
    def loops_at(gains: tuple) -> dict | None:
        try:
            return _loops_with(data, sections, dict(gains), machine, where)
        except (ConfigError, ValueError):
            return None

    def coupled_at(gains: dict, axis: str):
        """The coupled loop of ``axis`` with the contour controller's ``gains`` (None: not built)."""
        loops = loops_at(tuple(sorted(gains.items())))
        return loops[axis]["coupled"] if loops is not None else None

    axes = []
    for axis, loops in zero.items():
        if loops["coupled"] is None or loops["axis"] is None or any(unit[g][axis]["coupled"] is None for g in sizes):
            return None
        allowed = max(MS_LIMIT, quick_robustness(loops["axis"])[0])
        axes.append((loops["coupled"], {g: (unit[g][axis]["coupled"], sizes[g]) for g in sizes}, allowed,
                     functools.partial(coupled_at, axis=axis)))
    return GainScaledLoops(axes, MS_LIMIT)


def servo_loops(experiment) -> dict:
    """{axis: its loop alone as its servo's PID gains are scaled together
    (:class:`contouring_ros.core.margins.GainScaledLoops`, the loop zero without them)}: each gain's loop that
    of a PID servo with that gain alone (the servos whose PID this serves, the ZPETC's, run the same loop,
    :func:`contouring_ros.core.margins.axis_loop`), at the size of the servo's own kp; {} where an axis' loop
    is not linear."""
    ts = float(experiment.sample_time)
    out = {}
    for axis in experiment.axes:
        plant = build_plant(experiment, axis, 0.0, 0.0)
        size = gain_magnitude(experiment.servos[axis].get("kp", 0.0)) or 1.0
        sizes = {"kp": size, "ki": size * 2 * math.pi * 10.0, "kd": size * 1e-3}
        units = {}
        for gain, value in sizes.items():
            loop = axis_loop(plant, PIDServo(*(value if g == gain else 0.0 for g in sizes), ts), ts)
            if loop is None:
                return {}
            units[gain] = (loop, value)
        out[axis] = GainScaledLoops([(control.tf([0.0], [1.0], ts), units, MS_LIMIT, lambda gains, plant=plant: axis_loop(
            plant, PIDServo(gains["kp"], gains["ki"], gains["kd"], ts), ts))], MS_LIMIT)
    return out
