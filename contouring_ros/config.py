"""Experiment files: loading, validation and building the core objects.

An experiment is one ROS 2 parameter file. Keys shared by every node live under ``/**: ros__parameters``;
each node has its own section, named by its fully qualified node name::

    /**:            ros__parameters: {sample_time, duration, axes, curve, schedule, initial_state, ...}
    /<axis>/plant:  ros__parameters: {model, <model parameters>, disturbance}
    /<axis>/servo:  ros__parameters: {law, <law parameters>}
    /contour_estimator: ros__parameters: {type, <estimator parameters>}
    /ccc:           ros__parameters: {type, <controller parameters>}

Every key is checked before any node starts; a problem is reported in one line naming the file, the key
and what was expected. The nodes validate the parameters they receive with the same functions.
"""
from __future__ import annotations

import math
import os
import re
import stat
import sys
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

import numpy as np
import yaml

from . import graph
from .core import contouring, curves, disturbances, estimators, gcode, plants, servo
from .core.feed_planning import FeedPlan
from .core.interpolation import FeedrateSchedule, InPositionClock, UniformSchedule, reference
from .core.simulation import ControlLoop
from .errors import ConfigError
from .experiment.scenarios import resolve_part_program
from .graph import LOOKAHEAD, graph_namespace
from .registry import BuildContext, Role

__all__ = ["Experiment", "load_experiment", "parse_experiment", "read_yaml", "experiment_from_data", "build_loop",
           "build_curve",
           "build_schedule", "build_plant", "build_servo", "build_estimator", "build_controller",
           "initial_state", "controller_uses_state", "check_ccc_takes_state", "GLOBAL_SECTION", "node_sections", "section_from_parameters",
           "experiment_for_node", "namespaced_parameter_file"]

GLOBAL_SECTION = "/**"
ROS_PARAMETERS = "ros__parameters"
REQUIRED = object()
ROS_BUILTIN_PARAMETERS = {"use_sim_time", "start_type_description_service"}  # every rclpy node declares these


@dataclass(frozen=True)
class Param:
    """One expected key: its kind, default (REQUIRED if none), and the range it must lie in."""

    kind: str                     # float | int | str | bool | floats | strings | dict
    default: object = REQUIRED
    check: str | None = None      # positive | nonnegative
    choices: dict | tuple | None = None   # kind "dict" with a 'type': the registry of its types; kind "str": the
                                          # names allowed
    help: str = ""
    bounds: tuple | None = None   # (low, high), inclusive, for every number of the value (BOUNDS sets them;
                                  # without: DEFAULT_BOUNDS of its kind)


LIMIT = Param("float", 0.0, "nonnegative", help="output limit in command units, 0: none (anti-windup when hit)")


def _gains(**defaults):
    gains = {name: Param("float", defaults.get(name, REQUIRED), "nonnegative") for name in ("kp", "ki", "kd")}
    return {**gains, "output_limit": LIMIT}


TIMINGS = ("lockstep", "realtime")
INVALID_INPUT_POLICIES = ("stop", "hold")
OVERRUN_POLICIES = ("stop", "skip")
LAYOUTS = ("process", "composed", "grouped")    # where `contouring-ros run` puts the nodes (README, "Commands")
INITIAL_STATES = ("on_reference", "at_rest")
DISTURBANCE_UNITS = ("command", "acceleration")
# task-frame controllers: the local approximation they act on -> the estimator that reports its errors
APPROXIMATIONS = {"first_order": "tangent_line", "natural_local": "natural_local"}

# Registries, one per role: type name -> its parameters (defaults live here and nowhere else), the factory
# that builds its core object from a validated section and a BuildContext, and its constraints
# (contouring_ros/registry.py). Plugins add types through the entry point groups contouring_ros.<role>s.
DISTURBANCES = Role("disturbance")
CURVES = Role("curve")
SCHEDULES = Role("schedule")
PLANTS = Role("plant", "model")
SERVOS = Role("servo", "law")
ESTIMATORS = Role("estimator")
CONTROLLERS = Role("controller")


def _register(role: Role, specs: dict, builds: dict, **traits):
    """Register built-in types: ``builds`` name -> build(section, context); ``traits`` name -> Entry fields."""
    for name, params in specs.items():
        role.register(name, params, builds[name], origin="contouring_ros", **traits.get(name, {}))


def _spline(s, context):
    coordinates = [s["x"], s["y"]] + ([s["z"]] if s["z"] is not None else [])
    if len({len(c) for c in coordinates}) != 1:
        raise ValueError("x, y (and z) must list the same number of points")
    return curves.SplineCurve(np.column_stack(coordinates), s["closed"])


_PLAN_KEYS = ("rapid_feedrate", "axis_feedrate", "axis_acceleration", "axis_jerk", "contour_tolerance", "tracking_lag",
              "exact_stop_dwell", "feed_override", "in_position_timeout")


def _feedrate_schedule(section, context):
    """The feedrate schedule: with a ``jerk`` bound (always for a part program) the look-ahead, jerk-limited
    feed plan of a tool path (core/feed_planning.py); without, the acceleration-bounded profile."""
    arguments = _kwargs(section)
    where = context.where
    program = getattr(context.curve, "program", None)
    jerk = arguments.pop("jerk")
    plan = {key: arguments.pop(key) for key in _PLAN_KEYS}
    if jerk or program is not None:
        plan.pop("in_position_timeout")      # the reference's, not the plan's (build_clock)
        return _feed_plan(where, context.curve, program, jerk, arguments, plan)
    for key, value in plan.items():
        if value not in (None, 0.0) and (key, value) not in (("feed_override", 100.0), ("in_position_timeout", 0.5)):
            _fail(where, f"schedule.{key}", "applies to the jerk-limited feed plan of a tool path: give jerk too")
    if arguments["feedrate"] is None:
        _fail(where, "schedule.feedrate", "missing required key")
    for key, default in (("theta_start", context.curve.domain[0]), ("theta_end", context.curve.domain[1])):
        if arguments[key] is None:
            arguments[key] = default
    try:
        return FeedrateSchedule(context.curve, **arguments)
    except ValueError as error:
        raise ConfigError(f"{context.where}: schedule: {error}") from None


SLOW_NOTE_AFTER, SLOW_NOTE_EVERY = 3.0, 15.0     # s before the first note on stderr, then between notes


class note_while_slow:
    """Context manager: while its block runs longer than SLOW_NOTE_AFTER seconds, a line on stderr every
    SLOW_NOTE_EVERY seconds says ``what`` is still under way (on a terminal or not: a log shows it too)."""

    def __init__(self, what: str):
        self.what = what

    def __enter__(self):
        import threading
        import time
        self.done, started = threading.Event(), time.monotonic()

        def watch():
            wait = SLOW_NOTE_AFTER
            while not self.done.wait(wait):
                print(f"note: {self.what}: still under way after {time.monotonic() - started:.0f} s",
                      file=sys.stderr, flush=True)
                wait = SLOW_NOTE_EVERY
        threading.Thread(target=watch, daemon=True).start()
        return self

    def __exit__(self, *exc):
        self.done.set()
        return False


def _feed_plan(where, curve, program, jerk, arguments, plan):
    if not isinstance(curve, curves.ToolPath):
        _fail(where, "schedule.jerk", "the jerk-limited feed plan runs along a tool path (curve type toolpath or "
                                      "gcode)")
    if not jerk:
        _fail(where, "schedule.jerk", "missing required key (a part program is planned with a jerk bound)")
    for key in ("theta_start", "theta_end"):
        if arguments[key] is not None:
            _fail(where, f"schedule.{key}", "the feed plan covers the whole tool path: leave it out")
    if program is not None and program.has_feed_words and arguments["feedrate"] is not None:
        _fail(where, "schedule.feedrate", "the part program sets its feeds with F words: leave feedrate out")
    for key in ("axis_feedrate", "axis_acceleration", "axis_jerk", "tracking_lag"):
        if plan[key] is not None and len(plan[key]) not in (1, curve.dimension):
            _fail(where, f"schedule.{key}", f"expected 1 value or one per axis ({curve.dimension}), got "
                                            f"{len(plan[key])}")
    if plan["contour_tolerance"] and plan["tracking_lag"] is None:
        _fail(where, "schedule.tracking_lag", "missing required key (the contour-tolerance planner predicts the "
                                              "contour error from each axis' lag)")
    if plan["tracking_lag"] is not None and not plan["contour_tolerance"]:
        _fail(where, "schedule.tracking_lag", "used only with a contour_tolerance")
    try:
        with note_while_slow(f"{_printable(where)}: planning the feed along the tool path (a small jerk or "
                             "contour_tolerance plans many steps)"):
            return FeedPlan(curve, arguments["acceleration"], jerk, arguments["feedrate"], plan["rapid_feedrate"] or None,
                            arguments["normal_acceleration"], plan["axis_feedrate"], plan["axis_acceleration"],
                            plan["axis_jerk"], plan["contour_tolerance"], plan["tracking_lag"],
                            plan["exact_stop_dwell"], plan["feed_override"] / 100.0)
    except ValueError as error:
        raise ConfigError(f"{_printable(where)}: schedule: {_printable(error, 400)}") from None


def _gcode(s, context):
    """A part program's tool path; ``file`` is read relative to the experiment file (then the scenario
    directory, then the working directory)."""
    if len(s["start"]) not in (2, 3):
        raise ValueError(f"start: expected 2 or 3 coordinates [m], got {len(s['start'])}")
    path = resolve_part_program(s["file"], context.where)
    if path is None:
        raise ValueError(f"file: cannot find the part program {s['file']!r} (relative paths are read from the "
                         "experiment file's directory)")
    raw = _read_file(path, _printable(path), MAX_PROGRAM_BYTES, "a part program is a text file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as error:
        raise ValueError(f"{path}: not a text file (not UTF-8 at byte {error.start})") from None
    try:
        program = gcode.parse_program(text, s["start"], s["strict"])
        tool_path = curves.ToolPath.from_program(program, s["blend_tolerance"])
    except ValueError as error:
        raise ValueError(f"{path.name}: {error}") from None
    tool_path.program = program
    tool_path.source = str(path.resolve())
    return tool_path


def program_warnings(curve) -> list:
    """One line per kind of setup word the part program of ``curve`` read (none for other curves), naming
    the program file and the line."""
    program = getattr(curve, "program", None)
    if program is None:
        return []
    return [f"{Path(curve.source).name}: {warning}" for warning in program.warnings]


def _ismc(s, c):
    ts = c.sample_time
    observer = servo.DisturbanceObserver(s["c"], s["d"], s["gain"], s["time_constant"], ts, c.velocity,
                                         c.acceleration) if s["observer"] else None
    return servo.IntegralSlidingModeServo(s["a"], s["b"], s["mu"], s["kappa"], s["gain"], s["time_constant"],
                                          ts, observer, s["output_limit"])


#: the Newton estimate's branch check on a tool path: a sample every 50 um of path (at most 200 000), to
#: within 1 um. At an exact-stop corner the distance to the path is stationary at the kink, and Newton's
#: iteration stays there while the axes move on along the next block (the estimate then lags by the axes'
#: following error, 0.2 mm on the example part); 256 samples of a 0.2 m path are 0.8 mm apart, too sparse
#: to find the next block
TOOL_PATH_CHECK_SPACING, TOOL_PATH_CHECK_TOLERANCE = 5e-5, 1e-6
DEFAULT_CHECK_SAMPLES, DEFAULT_CHECK_TOLERANCE = 256, 1e-4


def branch_check_settings(section: dict, curve) -> tuple:
    """(samples, tolerance) of the Newton estimate's branch check: the section's, where it gives them, else
    256 points to 100 um, or on a tool path a point every TOOL_PATH_CHECK_SPACING to 1 um."""
    tool_path = isinstance(curve, curves.ToolPath)
    samples, tolerance = section["branch_check_samples"], section["branch_check_tolerance"]
    if samples is None:
        length = curve.domain[1] - curve.domain[0]
        samples = int(min(max(math.ceil(length / TOOL_PATH_CHECK_SPACING), DEFAULT_CHECK_SAMPLES), 200_000)) \
            if tool_path else DEFAULT_CHECK_SAMPLES
    if tolerance is None:
        tolerance = TOOL_PATH_CHECK_TOLERANCE if tool_path else DEFAULT_CHECK_TOLERANCE
    return samples, tolerance


def _newton(s, c):
    theta0 = s["theta0"] if s["theta0"] is not None else c.schedule.theta_start
    inner = s["inner_step"] or c.sample_time
    samples, tolerance = branch_check_settings(s, c.curve)
    check = estimators.BranchCheck(c.curve, samples, tolerance) if samples else None
    return estimators.NewtonEstimator(c.curve, s["k_prime"], s["c_prime"], theta0, inner, s["tolerance"],
                                      s["max_iterations"], check)


def _task_frame_pd(s, c):
    approximation = {"first_order": estimators.first_order_terms,
                     "natural_local": estimators.natural_local_terms}[s["approximation"]]
    return contouring.TaskFramePD(c.curve, approximation, s["mass"], s["damping"], s["gain"],
                                  [s["f_t"], s["f_n"]] + ([s["f_b"]] if s["f_b"] is not None else []), s["zeta"],
                                  s["coulomb_positive"], s["coulomb_negative"])


def _per_axis(name: str, keys: tuple):
    """A check: the Frenet-frame controller ``name`` needs 2 or 3 axes and one value per axis of ``keys``."""
    def check(section, axes):
        if len(axes) not in (2, 3):
            return "type", f"the {name} controller needs 2 or 3 axes (a Frenet frame)"
        for key in keys:
            if section[key] is not None and len(section[key]) != len(axes):
                return key, f"expected one value per axis ({len(axes)}), got {len(section[key])}"
        return None
    return check


_TASK_FRAME_PER_AXIS = _per_axis("task_frame_pd", ("mass", "damping", "gain", "coulomb_positive", "coulomb_negative"))


def _check_task_frame_pd(section, axes):
    if len(axes) == 3 and section["f_b"] is None:
        return "f_b", "missing required key (the binormal bandwidth, for 3 axes)"
    return _TASK_FRAME_PER_AXIS(section, axes)


def _task_frame_estimator(estimator, controller, servos):
    """task_frame_pd acts on the errors of the estimator of its approximation."""
    expected = APPROXIMATIONS[controller["approximation"]]
    if estimator["type"] != expected:
        return ("/contour_estimator.type", f"the task_frame_pd controller with approximation "
                f"{controller['approximation']!r} acts on the errors of the {expected!r} estimator, got "
                f"{estimator['type']!r}")
    return None


_register(DISTURBANCES, {
    "none": {},
    "constant": {"value": Param("float")},
    "sinusoid": {"amplitude": Param("float"), "frequency": Param("float", check="positive"),
                 "phase": Param("float", 0.0), "offset": Param("float", 0.0)},
    "random": {"std": Param("float", check="nonnegative"), "seed": Param("int", 0, "nonnegative"),
               "offset": Param("float", 0.0)},
}, {
    "none": lambda s, c: disturbances.NoDisturbance(),
    "constant": lambda s, c: disturbances.ConstantDisturbance(s["value"]),
    "sinusoid": lambda s, c: disturbances.SinusoidalDisturbance(**_kwargs(s)),
    "random": lambda s, c: disturbances.RandomDisturbance(**_kwargs(s)),
})
WINDOW = Param("float", 0.0, "nonnegative", help="curve-parameter half-width the exact contour error searches "
                                                "around the reference point; 0: the whole curve")
_CURVE_SPECS = {
    "parabola": {"a": Param("float", check="positive"), "h": Param("float")},
    "circle": {"radius": Param("float", check="positive"), "center": Param("floats", [0.0, 0.0])},
    "line": {"start": Param("floats"), "end": Param("floats")},
    "ellipse": {"a": Param("float", check="positive"), "b": Param("float", check="positive"),
                "center": Param("floats", [0.0, 0.0])},
    "figure_eight": {"a": Param("float", check="positive"), "b": Param("float", check="positive"),
                     "center": Param("floats", [0.0, 0.0])},
    "butterfly": {"scale": Param("float", check="positive"), "center": Param("floats", [0.0, 0.0])},
    "saddle": {"a": Param("float", check="positive"), "b": Param("float", check="positive"),
               "h": Param("float"), "omega": Param("float", 6.283185307179586)},
    "spline": {"x": Param("floats"), "y": Param("floats"), "z": Param("floats", None), "closed": Param("bool", False)},
    "toolpath": {"start": Param("floats"), "moves": Param("strings")},
    "gcode": {"file": Param("str"), "start": Param("floats", [0.0, 0.0, 0.0]),
              "blend_tolerance": Param("float", 0.0, "nonnegative", help="m, as G64 P; 0: exact stop (G61)"),
              "strict": Param("bool", False)},
    "helix": {"a": Param("float", check="positive"), "b": Param("float", check="positive"), "c": Param("float"),
              "omega": Param("float"), "length": Param("float", check="positive")},
}
for _spec in _CURVE_SPECS.values():
    _spec["contour_error_window"] = WINDOW
_register(CURVES, _CURVE_SPECS, {
    "parabola": lambda s, c: curves.Parabola(s["a"], s["h"]),
    "circle": lambda s, c: curves.Circle(s["radius"], s["center"]),
    "line": lambda s, c: curves.Line(s["start"], s["end"]),
    "ellipse": lambda s, c: curves.Ellipse(s["a"], s["b"], s["center"]),
    "figure_eight": lambda s, c: curves.FigureEight(s["a"], s["b"], s["center"]),
    "butterfly": lambda s, c: curves.Butterfly(s["scale"], s["center"]),
    "saddle": lambda s, c: curves.Saddle(s["a"], s["b"], s["h"], s["omega"]),
    "spline": _spline,
    "toolpath": lambda s, c: curves.ToolPath(s["start"], s["moves"]),
    "gcode": _gcode,
    "helix": lambda s, c: curves.Helix(s["a"], s["b"], s["c"], s["omega"], s["length"]),
})
_register(SCHEDULES, {
    "uniform": {"theta_start": Param("float"), "theta_end": Param("float"),
                "duration": Param("float", check="positive")},
    "feedrate": {"theta_start": Param("float", None), "theta_end": Param("float", None),  # default: the curve's domain
                 # default: none (a part program's F words give it)
                 "feedrate": Param("float", None, "positive"), "acceleration": Param("float", check="positive"),
                 "normal_acceleration": Param("float", 0.0, "nonnegative"),
                 "samples": Param("int", 20001, "positive"),
                 # the jerk-limited feed plan of a tool path (core/feed_planning.py); jerk 0: not jerk-limited
                 "jerk": Param("float", 0.0, "nonnegative"), "rapid_feedrate": Param("float", 0.0, "nonnegative"),
                 "axis_feedrate": Param("floats", None), "axis_acceleration": Param("floats", None),
                 "axis_jerk": Param("floats", None),
                 "contour_tolerance": Param("float", 0.0, "nonnegative"),
                 "tracking_lag": Param("floats", None), "exact_stop_dwell": Param("float", 0.0, "nonnegative"),
                 "feed_override": Param("float", 100.0, "positive"),
                 "in_position_timeout": Param("float", 0.5, "positive")},
}, {
    "uniform": lambda s, c: UniformSchedule(**_kwargs(s)),
    "feedrate": _feedrate_schedule,
})
# the imperfections of a real feed drive, every plant type (core/plants.py, Axis): all off by default
_MACHINE = {"encoder_resolution": Param("float", 0.0, "nonnegative"),
            "measurement_noise": Param("float", 0.0, "nonnegative"),
            "noise_seed": Param("int", 0, "nonnegative"),
            "command_delay": Param("int", 0, "nonnegative"),
            "velocity_measurement": Param("str", "model", choices=plants.VELOCITY_MEASUREMENTS)}


def _machine(s) -> dict:
    return {key: s[key] for key in _MACHINE}


_register(PLANTS, {
    "first_order_velocity": {"gain": Param("float", check="positive"),
                             "time_constant": Param("float", check="positive"),
                             "disturbance": Param("dict", {"type": "none"}, choices=DISTURBANCES),
                             "saturation": LIMIT, **_MACHINE},
    "mass_damper": {"mass": Param("float", check="positive"), "damping": Param("float", check="nonnegative"),
                    "gain": Param("float", check="positive"),
                    "coulomb_positive": Param("float", 0.0, "nonnegative"),
                    "coulomb_negative": Param("float", 0.0, "nonnegative"),
                    "disturbance": Param("dict", {"type": "none"}, choices=DISTURBANCES),
                    "disturbance_unit": Param("str", "command", choices=DISTURBANCE_UNITS),
                    "saturation": LIMIT, **_MACHINE},
}, {
    "first_order_velocity": lambda s, c: plants.FirstOrderVelocityAxis(
        s["gain"], s["time_constant"], c.sample_time, build_disturbance(s["disturbance"]), c.position, c.velocity,
        s["saturation"], **_machine(s)),
    "mass_damper": lambda s, c: plants.MassDamperAxis(
        s["mass"], s["damping"], s["gain"], c.sample_time, build_disturbance(s["disturbance"]), c.position,
        c.velocity, s["saturation"], s["coulomb_positive"], s["coulomb_negative"], s["disturbance_unit"],
        **_machine(s)),
})
_SERVO_SPECS = {
    "pid_feedforward": {**_gains(), "gain": Param("float", check="positive"),
                        "time_constant": Param("float", check="nonnegative")},
    "ismc": {"a": Param("float", check="positive"), "b": Param("float", check="positive"),
             "mu": Param("float", check="positive"), "kappa": Param("float", check="positive"),
             "gain": Param("float", check="positive"), "time_constant": Param("float", check="positive"),
             "observer": Param("bool", False), "c": Param("float", 1.0, "positive"),
             "d": Param("float", 1.0, "positive"), "output_limit": LIMIT},
    "direct": {"output_limit": LIMIT},
    "pid": _gains(ki=0.0, kd=0.0),
    "cascade": {"kp_position": Param("float", check="nonnegative"), "kp_velocity": Param("float", check="nonnegative"),
                "ki_velocity": Param("float", 0.0, "nonnegative"), "coulomb_positive": Param("float", 0.0, "nonnegative"),
                "coulomb_negative": Param("float", 0.0, "nonnegative"), "output_limit": LIMIT},
    "eso_smc": {"mass": Param("float", check="positive"), "damping": Param("float", check="nonnegative"),
                "gain": Param("float", check="positive"), "c": Param("float", check="positive"),
                "k": Param("float", check="positive"), "alphas": Param("floats"),
                "sigma": Param("float", check="positive"), "disturbance_compensation": Param("bool", True),
                "output_limit": LIMIT},
}
_register(SERVOS, _SERVO_SPECS, {
    "pid_feedforward": lambda s, c: servo.PIDFeedforwardServo(s["kp"], s["ki"], s["kd"], s["gain"], s["time_constant"],
                                                              c.sample_time, s["output_limit"]),
    "ismc": _ismc,
    "direct": lambda s, c: servo.DirectServo(s["output_limit"]),
    "pid": lambda s, c: servo.PIDServo(s["kp"], s["ki"], s["kd"], c.sample_time, s["output_limit"]),
    "cascade": lambda s, c: servo.CascadeServo(s["kp_position"], s["kp_velocity"], s["ki_velocity"], c.sample_time,
                                               s["coulomb_positive"], s["coulomb_negative"], s["output_limit"]),
    "eso_smc": lambda s, c: servo.ESOSlidingModeServo(s["mass"], s["damping"], s["gain"], s["c"], s["k"], s["alphas"],
                                                      s["sigma"], c.sample_time, c.position, c.velocity,
                                                      s["disturbance_compensation"], s["output_limit"]),
}, direct={"direct": True}, eso_smc={"check": lambda s, axes: None if len(s["alphas"]) == 3 else (
    "alphas", f"expected the three ESO gains alpha_1..3, got {len(s['alphas'])}")})
_register(ESTIMATORS, {
    "tangent_line": {},
    "natural_local": {},
    "osculating_circle": {},
    "foot_point_search": {"max_iterations": Param("int", 10, "positive"),
                          "tolerance": Param("float", 1e-6, "positive")},
    "newton": {"k_prime": Param("float", check="positive"), "c_prime": Param("float", check="positive"),
               "tolerance": Param("float", 1e-9, "positive"),           # m: inner iterations until converged
               "max_iterations": Param("int", 200, "positive"),         # inner iterations per step at most
               "inner_step": Param("float", 0.0, "nonnegative"),
               "theta0": Param("float", None),
               # None: 256 points, and on a tool path one every TOOL_PATH_CHECK_SPACING (its corners); 0: no check
               "branch_check_samples": Param("int", None, "nonnegative"),
               "branch_check_tolerance": Param("float", None, "positive")},   # m; None: 1e-4, 1e-6 on a tool path
}, {
    "tangent_line": lambda s, c: estimators.TangentLineEstimator(c.curve),
    "natural_local": lambda s, c: estimators.NaturalLocalEstimator(c.curve),
    "osculating_circle": lambda s, c: estimators.OsculatingCircleEstimator(c.curve),
    "foot_point_search": lambda s, c: estimators.FootPointSearchEstimator(c.curve, s["max_iterations"], s["tolerance"]),
    "newton": _newton,
}, osculating_circle={"check": lambda s, axes: None if len(axes) == 2 else (
    "type", "the osculating_circle estimate needs a planar contour (2 axes)")})
_register(CONTROLLERS, {
    "none": {},
    "variable_gain": _gains(),
    "unit_vector": _gains(),
    "task_frame_pd": {"approximation": Param("str", choices=tuple(APPROXIMATIONS)), "mass": Param("floats"), "damping": Param("floats"),
                      "gain": Param("floats"), "coulomb_positive": Param("floats", None),
                      "coulomb_negative": Param("floats", None), "f_t": Param("float", check="positive"),
                      "f_n": Param("float", check="positive"), "f_b": Param("float", None, "positive"),
                      "zeta": Param("float", 1.0, "positive")},
    "tvt": {"kc": Param("float", check="nonnegative"), "min_feedrate": Param("float", 1e-3, "nonnegative")},
    "adaptive_tnb": {"coupling": Param("floats"), "alpha": Param("float", check="positive"),
                     "gamma_mass": Param("floats"), "gamma_damping": Param("floats"), "mass0": Param("floats"),
                     "damping0": Param("floats")},
}, {
    "none": lambda s, c: contouring.NoCoupling(c.n_axes),
    "variable_gain": lambda s, c: contouring.VariableGainCCC(c.curve, s["kp"], s["ki"], s["kd"], c.sample_time,
                                                             s["output_limit"]),
    "unit_vector": lambda s, c: contouring.UnitVectorCCC(c.n_axes, s["kp"], s["ki"], s["kd"], c.sample_time,
                                                         s["output_limit"]),
    "task_frame_pd": _task_frame_pd,
    "tvt": lambda s, c: contouring.TangentialVelocityCCC(c.curve, c.schedule, s["kc"], s["min_feedrate"]),
    "adaptive_tnb": lambda s, c: contouring.AdaptiveTNBCCC(c.curve, s["coupling"], s["alpha"], s["gamma_mass"],
                                                           s["gamma_damping"], s["mass0"], s["damping0"],
                                                           c.sample_time),
}, task_frame_pd={"whole_command": True, "check": _check_task_frame_pd, "combination": _task_frame_estimator},
    tvt={"whole_command": True},
    adaptive_tnb={"check": _per_axis("adaptive_tnb", ("coupling", "gamma_mass", "gamma_damping", "mass0",
                                                       "damping0"))})
# built-in controllers that compute every axis' whole command (their servos must be 'direct', and only theirs;
# a plugin says so with whole_command on its entry)
WHOLE_COMMAND_CONTROLLERS = {name for name, entry in CONTROLLERS._entries.items() if entry.whole_command}
GLOBALS = {
    "experiment": Param("dict", {}),
    "paper": Param("dict", {}),
    "sample_time": Param("float", check="positive"),
    "duration": Param("float", 0.0, "nonnegative"),
    "settle_time": Param("float", 0.0, "nonnegative"),   # s run past the schedule's end (duration left to it)
    "axes": Param("strings"),
    "curve": Param("dict", choices=CURVES),
    "schedule": Param("dict", choices=SCHEDULES),
    "initial_state": Param("str", "on_reference", choices=INITIAL_STATES),
    "network": Param("bool", False),          # discover nodes beyond localhost
    "stall_timeout": Param("float", 10.0, "positive"),   # s without a complete step before a node gives up
    # s a node waits at start for the rest of the graph (hand-started nodes in separate terminals need time)
    "graph_timeout": Param("float", 300.0, "positive"),
    # a run has diverged once an axis is this many path sizes from its reference (0: never stop for that)
    "divergence_factor": Param("float", 10.0, "nonnegative"),
    "on_invalid_input": Param("str", "stop", choices=INVALID_INPUT_POLICIES),  # what a node does with a
                                                                             # non-finite or malformed input
    "timing": Param("str", "lockstep", choices=TIMINGS),   # docs/ARCHITECTURE.md, "One control step"
    "start_time": Param("float", 0.0, "nonnegative"),  # realtime: Unix time of tick 0 (the runner sets it)
    # realtime: s a node (or a group's loop) may fall behind its ticks before on_overrun acts
    "max_lag": Param("float", 0.02, "positive"),
    # realtime, past max_lag: stop the run with one line (like a drive's following-error trip), or skip to
    # the tick now due and count the skipped ones
    "on_overrun": Param("str", "stop", choices=OVERRUN_POLICIES),
    # where `contouring-ros run` puts the nodes: a process each, all in one, or the processes of `groups`
    # ("x/plant,x/servo; y/plant,y/servo"; a node in no group runs alone); --composed/--group/--process win
    "layout": Param("str", "process", choices=LAYOUTS),
    "groups": Param("str", ""),
    # whether the CCC subscribes to /reference and the states: contouring-ros run sets false where the
    # controller does not use them (3 fewer deliveries a step with 2 axes); true is always safe
    "ccc_takes_state": Param("bool", True),
    # m, one value or one per axis: the drives' in-position window; on a tool path an exact stop waits until
    # every axis' following error is within it (0: no wait, the plan's own time)
    "in_position": Param("floats", [1e-5]),
    # under a namespace: /clock and /diagnostics stay global (false: what use_sim_time nodes and diagnostic
    # aggregators listen to) or take the namespace too (true: several graphs sharing a domain, each its clock)
    "namespaced_clock": Param("bool", False),
}
# node section -> (key holding the type name, registry)
ROLE_TYPES = {"plant": ("model", PLANTS), "servo": ("law", SERVOS),
              "contour_estimator": ("type", ESTIMATORS), "ccc": ("type", CONTROLLERS)}
# nodes whose section may be left out, with the keys they take
OPTIONAL_NODES = {"interpolator": {}, "recorder": {"bag": Param("str", ""), "experiment_file": Param("str", "")}}

# --- bounds: every number a file gives lies in a stated range, so no run starts that cannot end or fit --------
MAX_FILE_BYTES = 1 << 20        # an experiment file (UTF-8 text) is at most 1 MiB
MAX_PROGRAM_BYTES = 256 << 20   # a part program at most 256 MiB (a million short blocks take tens of MB)
MAX_DEPTH = 16                  # levels of YAML nesting (the shipped files use 6)
MAX_STEPS = 10_000_000          # control steps of one run: duration / sample_time + 1
MAX_DURATION = 3600.0           # s of simulated time
MAX_ITEMS = 4096                # items of one list
MAX_EVENTS = 20_000             # YAML parser events of one file (values, keys, collections); a scenario has ~300
MAX_TEXT = 256                  # characters of one string value
NUMERIC_KINDS = ("float", "int", "floats")
DEFAULT_BOUNDS = {"float": (-1e12, 1e12), "floats": (-1e12, 1e12), "int": (-2 ** 31, 2 ** 31 - 1)}
_GAIN, _POSITIVE, _LIMIT = (0.0, 1e12), (1e-12, 1e12), (0.0, 1e12)
_SIZE, _COORDINATE = (1e-9, 1e3), (-1e3, 1e3)              # m
_MASS, _DAMPING, _FORCE = (1e-9, 1e9), (0.0, 1e9), (0.0, 1e9)
_AXIS_GAIN, _TIME_CONSTANT = (1e-9, 1e9), (1e-6, 1e3)      # command units -> m/s (or N); s
# registry -> {key: (low, high)} for that key in every type of the registry, or {"type.key": ...} for one type
BOUNDS = {
    "GLOBALS": {"sample_time": (1e-5, 1.0), "duration": (0.0, MAX_DURATION), "settle_time": (0.0, MAX_DURATION),
                "stall_timeout": (1e-3, 3600.0), "graph_timeout": (1e-3, 86400.0), "start_time": (0.0, 1e10),
                "divergence_factor": (0.0, 1e6), "max_lag": (1e-6, 3600.0),
                "in_position": (0.0, 1e-2)},
    "CURVES": {"a": _SIZE, "b": _SIZE, "radius": _SIZE, "scale": _SIZE, "length": (1e-9, 1e6), "h": (-1e3, 1e3),
               "c": (-1e3, 1e3), "omega": (-1e4, 1e4), "center": _COORDINATE, "start": _COORDINATE,
               "end": _COORDINATE, "x": _COORDINATE, "y": _COORDINATE, "z": _COORDINATE,
               "contour_error_window": (0.0, 1e6), "blend_tolerance": (0.0, 1e-2)},
    "SCHEDULES": {"theta_start": (-1e6, 1e6), "theta_end": (-1e6, 1e6), "duration": (1e-6, MAX_DURATION),
                  "feedrate": (1e-6, 100.0), "acceleration": (1e-6, 1e5), "normal_acceleration": (0.0, 1e5),
                  "samples": (2, 1_000_000), "jerk": (0.0, 1e7), "rapid_feedrate": (0.0, 100.0),
                  "axis_feedrate": (1e-6, 100.0), "axis_acceleration": (1e-6, 1e5), "axis_jerk": (1e-6, 1e7),
                  "contour_tolerance": (0.0, 1e-2), "tracking_lag": (0.0, 10.0), "exact_stop_dwell": (0.0, 60.0),
                  "feed_override": (1.0, 1000.0), "in_position_timeout": (1e-3, 60.0)},
    "DISTURBANCES": {"value": (-1e9, 1e9), "amplitude": (-1e9, 1e9), "offset": (-1e9, 1e9),
                     "frequency": (1e-6, 1e5), "phase": (-1e3, 1e3), "std": (0.0, 1e9), "seed": (0, 2 ** 32 - 1)},
    "PLANTS": {"gain": _AXIS_GAIN, "time_constant": _TIME_CONSTANT, "mass": _MASS, "damping": _DAMPING,
               "coulomb_positive": _FORCE, "coulomb_negative": _FORCE, "saturation": _LIMIT,
               "encoder_resolution": (0.0, 1.0), "measurement_noise": (0.0, 1.0), "noise_seed": (0, 2 ** 32 - 1),
               "command_delay": (0, plants.MAX_COMMAND_DELAY)},
    "SERVOS": {"kp": _GAIN, "ki": _GAIN, "kd": _GAIN, "kp_position": _GAIN, "kp_velocity": _GAIN,
               "ki_velocity": _GAIN, "output_limit": _LIMIT, "gain": _AXIS_GAIN, "time_constant": _TIME_CONSTANT,
               "pid_feedforward.time_constant": (0.0, 1e3), "a": _POSITIVE, "b": _POSITIVE, "mu": _POSITIVE,
               "kappa": _POSITIVE, "c": _POSITIVE, "d": _POSITIVE, "k": _POSITIVE, "sigma": _POSITIVE,
               "alphas": _GAIN, "mass": _MASS, "damping": _DAMPING, "coulomb_positive": _FORCE,
               "coulomb_negative": _FORCE},
    "ESTIMATORS": {"foot_point_search.max_iterations": (1, 1000), "newton.max_iterations": (1, 10_000),
                   "tolerance": (1e-15, 1.0), "k_prime": _POSITIVE, "c_prime": _POSITIVE, "inner_step": (0.0, 1.0),
                   "theta0": (-1e6, 1e6), "branch_check_samples": (0, 10_000),
                   "branch_check_tolerance": (1e-15, 1e3)},
    "CONTROLLERS": {"kp": _GAIN, "ki": _GAIN, "kd": _GAIN, "output_limit": _LIMIT, "mass": _MASS,
                    "damping": _DAMPING, "gain": _AXIS_GAIN, "coulomb_positive": _FORCE, "coulomb_negative": _FORCE,
                    "f_t": (1e-6, 1e5), "f_n": (1e-6, 1e5), "f_b": (1e-6, 1e5), "zeta": (1e-6, 1e3), "kc": _GAIN,
                    "min_feedrate": (0.0, 100.0), "coupling": (-1e12, 1e12), "alpha": _POSITIVE,
                    "gamma_mass": _GAIN, "gamma_damping": _GAIN, "mass0": _MASS, "damping0": _DAMPING},
}


def _registries() -> dict:
    """BOUNDS' registry names -> {type name: its Params} (GLOBALS as one type)."""
    return {"GLOBALS": {"": GLOBALS}, **{name: role.builtin() for name, role in _ROLES_BY_BOUNDS.items()}}


def _apply_bounds():
    """Give every numeric Param named in BOUNDS its range (one type's own entry before the registry's)."""
    registries = _registries()
    for registry, table in BOUNDS.items():
        for type_name, specs in registries[registry].items():
            for key, spec in specs.items():
                bounds = table.get(f"{type_name}.{key}", table.get(key))
                if bounds is not None and spec.kind in NUMERIC_KINDS:
                    specs[key] = replace(spec, bounds=bounds)


_ROLES_BY_BOUNDS = {"CURVES": CURVES, "SCHEDULES": SCHEDULES, "DISTURBANCES": DISTURBANCES, "PLANTS": PLANTS,
                    "SERVOS": SERVOS, "ESTIMATORS": ESTIMATORS, "CONTROLLERS": CONTROLLERS}
_apply_bounds()


def _plugin_params(table: dict):
    """What each plugin type's parameters go through as it loads: every value a Param; a numeric one
    without bounds of its own gets its role's BOUNDS for that key (else its kind's defaults)."""
    def check(entry):
        for key, spec in entry.params.items():
            if not isinstance(spec, Param):
                raise TypeError(f"params[{key!r}]: expected a contouring_ros.config.Param, got {type(spec).__name__}")
            if not _PARAMETER_NAME.match(key) or key in ("type", "law", "model"):
                raise TypeError(f"params[{key!r}]: not a usable parameter name")
            bounds = table.get(f"{entry.name}.{key}", table.get(key))
            if spec.bounds is None and bounds is not None and spec.kind in NUMERIC_KINDS:
                entry.params[key] = replace(spec, bounds=bounds)
    return check


for _name, _role in _ROLES_BY_BOUNDS.items():
    _role.on_register = _plugin_params(BOUNDS[_name])


@dataclass(frozen=True)
class Experiment:
    """A validated experiment. Sections are plain dicts with every default filled in."""

    path: str
    text: str
    sample_time: float
    duration: float
    axes: tuple
    curve: dict
    schedule: dict
    initial_state: str
    network: bool = False
    stall_timeout: float = 10.0
    graph_timeout: float = 300.0
    divergence_factor: float = 10.0
    on_invalid_input: str = "stop"
    timing: str = "lockstep"
    start_time: float = 0.0
    max_lag: float = 0.02
    on_overrun: str = "stop"
    layout: str = "process"
    groups: str = ""
    ccc_takes_state: bool = True
    in_position: tuple = (1e-5,)                   # m, one or one per axis (0: exact stops do not wait)
    namespaced_clock: bool = False
    plants: dict = field(default_factory=dict)     # axis -> plant section
    servos: dict = field(default_factory=dict)     # axis -> servo section
    estimator: dict = field(default_factory=dict)
    controller: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)       # 'experiment' and 'paper' blocks, free-form

    @property
    def n_steps(self) -> int:
        """Steps k = 0 .. n_steps - 1 cover t = 0 .. duration inclusive."""
        return int(round(self.duration / self.sample_time)) + 1

    @property
    def name(self) -> str:
        return str(self.info.get("experiment", {}).get("name", Path(self.path).stem))


try:    # libyaml's parser (the one the ROS 2 parameter parser uses) when PyYAML has it: 5x faster
    from yaml._yaml import CParser as _CParser
except ImportError:
    _CParser = None
_LOADER_BASES = (yaml.composer.Composer, _CParser, yaml.constructor.SafeConstructor, yaml.resolver.Resolver) \
    if _CParser is not None else (yaml.SafeLoader,)


class _NoAliasLoader(*_LOADER_BASES):
    """YAML loader that refuses anchors/aliases, so no file can expand without bound, and reads every
    exponent float (1e-3, 4.86e7) as a number, as YAML 1.2 and the ROS parameter parser do.

    It also refuses explicit tags (!!float 1: the ROS parser ignores them) and nesting deeper than MAX_DEPTH,
    and names the key of every problem it finds; :meth:`check_ros` holds a document to the ROS parser."""

    _path: list
    _depth = 0

    def __init__(self, text: str):
        if _CParser is None:
            yaml.SafeLoader.__init__(self, text)
            return
        _CParser.__init__(self, text)
        yaml.composer.Composer.__init__(self)
        yaml.constructor.SafeConstructor.__init__(self)
        yaml.resolver.Resolver.__init__(self)

    def _refuse(self, mark, message: str, path=None):
        key = _key_name(self._path if path is None else path)
        raise ConfigError(f"{key + ': ' if key else ''}line {mark.line + 1}: {message}")

    def compose_node(self, parent, index):
        if not hasattr(self, "_path"):
            self._path = []
        event = self.peek_event()
        label = None if parent is None or index is None else (index.value if isinstance(index, yaml.ScalarNode)
                                                               else f"[{index}]")
        if label is not None:
            self._path.append(label)
        self._depth += 1
        try:
            if self.check_event(yaml.AliasEvent):
                self._refuse(event.start_mark, "YAML aliases (*name) are not allowed in experiment files")
            if self._depth > MAX_DEPTH:
                self._refuse(event.start_mark, f"nested deeper than {MAX_DEPTH} levels")
            tag = getattr(event, "tag", None)
            if tag not in (None, "!"):
                self._refuse(event.start_mark, f"explicit YAML tags ({_show(tag)}) are not allowed in experiment "
                                               "files (the ROS 2 parser ignores them)")
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1
            if label is not None:
                self._path.pop()

    def fetch_flow_collection_start(self, TokenClass):
        # the scanner's own nesting ([[[[... or {a: {a: ...), refused before its cost grows with the depth
        if self.flow_level >= MAX_DEPTH:
            self._refuse(self.get_mark(), f"nested deeper than {MAX_DEPTH} levels")
        super().fetch_flow_collection_start(TokenClass)

    def check_ros(self, root):
        """Refuse what the ROS 2 parameter parser (rcl_yaml_param_parser) reads differently from this
        loader, or refuses: a scalar of another type or value (bare y/n read as booleans, 1:30, 1_000,
        integers beyond 64 bits, ~ and null, dates, 0x1p3, nan, denormals), an empty value, list or
        mapping, a list of mixed types or of lists or mappings, a key that is not a plain ASCII name."""
        if not isinstance(root, yaml.MappingNode):
            return
        for section_key, section in root.value:
            if not isinstance(section, yaml.MappingNode):
                continue
            for body_key, body in section.value:
                if isinstance(body, yaml.MappingNode):
                    self._check_ros_mapping(body, [section_key.value, body_key.value])

    def _check_ros_mapping(self, node, path):
        if not node.value:
            self._refuse(node.start_mark, "an empty mapping: ROS 2 gives it no value (leave the key out)", path)
        for key_node, value_node in node.value:
            here = path + [key_node.value if isinstance(key_node, yaml.ScalarNode) else "?"]
            key = self._construct(key_node, here) if isinstance(key_node, yaml.ScalarNode) else None
            if not isinstance(key, str):
                self._refuse(key_node.start_mark, f"the key {_show(getattr(key_node, 'value', key_node))} is read "
                                                  f"as {_described(key)}, ROS 2 reads a name: quote it", here)
            if not _PARAMETER_NAME.match(key):
                self._refuse(key_node.start_mark, "a parameter name is 1 to 64 ASCII letters, digits and _ "
                                                  "(not starting with a digit)", here)
            if isinstance(value_node, yaml.MappingNode):
                self._check_ros_mapping(value_node, here)
            elif isinstance(value_node, yaml.SequenceNode):
                self._check_ros_sequence(value_node, here)
            else:
                self._check_ros_scalar(value_node, here)

    def _check_ros_sequence(self, node, path):
        if not node.value:
            self._refuse(node.start_mark, "an empty list: ROS 2 cannot give it a type (leave the key out or "
                                          "give at least one item)", path)
        if len(node.value) > MAX_ITEMS:
            self._refuse(node.start_mark, f"expected at most {MAX_ITEMS} items, got {len(node.value)}", path)
        kinds = []
        for index, item in enumerate(node.value):
            if not isinstance(item, yaml.ScalarNode):
                what = "list" if isinstance(item, yaml.SequenceNode) else "mapping"
                self._refuse(item.start_mark, f"item {index + 1} is a {what}: a ROS 2 list parameter holds plain "
                                              "values only", path)
            kinds.append(self._check_ros_scalar(item, path, index))
        if len(set(kinds)) > 1:
            if set(kinds) == {"integer", "double"}:
                first = kinds.index("integer")
                self._refuse(node.start_mark, f"a list of integers and decimals (item {first + 1} is "
                                              f"{_show(node.value[first].value)}): ROS 2 refuses a list of mixed "
                                              "types; write every number with a decimal point", path)
            self._refuse(node.start_mark, f"a list of mixed types ({', '.join(dict.fromkeys(kinds))}) as ROS 2 "
                                          "reads it: ROS 2 refuses it; quote names that read as booleans (y, n, "
                                          "on, off ...)", path)

    def _construct(self, node, path):
        try:
            return self.construct_object(node)
        except (ValueError, OverflowError) as error:     # e.g. an integer of more than 4300 digits
            self._refuse(node.start_mark, f"cannot read {_show(node.value)} ({_printable(error, 100)})", path)

    def _check_ros_scalar(self, node, path, index=None) -> str:
        kind, ros = _ros_scalar(node.value, node.style)
        where = "" if index is None else f"item {index + 1}: "
        if kind == "empty":
            self._refuse(node.start_mark, f"{where}no value (ROS 2 refuses an empty value)", path)
        ours = self._construct(node, path)
        agree = {"bool": lambda: type(ours) is bool and ours == ros,
                 "integer": lambda: type(ours) is int and ours == ros,
                 "double": lambda: type(ours) is float and (ours == ros or (math.isnan(ours) and math.isnan(ros))),
                 "string": lambda: type(ours) is str and ours == ros}[kind]()
        if not agree:
            hint = {"bool": f"quote it ('{node.value}') for a name", "string": "write a plain number, or quote it "
                    "for a name", "integer": "quote it for a name", "double": "write a plain decimal number, or "
                    "quote it for a name"}[kind]
            if kind == "double" and type(ours) is int:
                hint = "integers are 64-bit in ROS 2"
            if ours is None:
                hint = "give a value or leave the key out"
            self._refuse(node.start_mark, f"{where}ROS 2 reads {_show(node.value)} as {_described(ros, kind)}, not "
                                          f"as {_described(ours)}: {hint}", path)
        return kind


_NoAliasLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float", re.compile(r"^[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."))
_PARAMETER_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]{0,63}$")
_AXIS_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,31}$")
_EXPERIMENT_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}$")
RESERVED_AXIS_NAMES = {"theta", "contour_error", "foot_point_parameter"}   # other joint names of the messages
_PLAIN_INTEGER = re.compile(r"^[-+]?(?:0|[1-9][0-9]{0,17})$")
_PLAIN_DECIMAL = re.compile(r"^[-+]?(?:[0-9]+\.[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]{1,3})?$")
_ROS_TRUE = {"Y", "y", "yes", "Yes", "YES", "true", "True", "TRUE", "on", "On", "ON"}
_ROS_FALSE = {"N", "n", "no", "No", "NO", "false", "False", "FALSE", "off", "Off", "OFF"}
_ROS_SPECIAL_FLOATS = {".nan": math.nan, ".NaN": math.nan, ".NAN": math.nan, ".inf": math.inf, ".Inf": math.inf,
                       ".INF": math.inf, "+.inf": math.inf, "+.Inf": math.inf, "+.INF": math.inf,
                       "-.inf": -math.inf, "-.Inf": -math.inf, "-.INF": -math.inf}


def _ros_scalar(value: str, style) -> tuple:
    """How rcl_yaml_param_parser reads one scalar (its get_value: booleans, then C strtol with base 0, then
    strtod, else a string; quoted scalars are strings): (kind, value), kind bool | integer | double |
    string | empty."""
    if style in ("'", '"'):
        return "string", value
    if value == "":
        return "empty", None
    if value in _ROS_TRUE or value in _ROS_FALSE:
        return "bool", value in _ROS_TRUE
    if value in _ROS_SPECIAL_FLOATS:
        return "double", _ROS_SPECIAL_FLOATS[value]
    if _PLAIN_INTEGER.match(value):     # the common forms, read as strtol / strtod read them, without a C call
        return "integer", int(value)
    if _PLAIN_DECIMAL.match(value):
        number = float(value)
        mantissa = re.split("[eE]", value)[0]
        if math.isfinite(number) and (abs(number) >= sys.float_info.min or not re.search("[1-9]", mantissa)):
            return "double", number       # (strtod: a range error for a denormal or an overflow)
    integer = _c_strtol(value)
    if integer is not None:
        return "integer", integer
    number = _c_strtod(value)
    if number is not None:
        return "double", number
    return "string", value


def _libc():
    global _LIBC
    if _LIBC is None:
        try:
            import ctypes
            libc = ctypes.CDLL(None, use_errno=True)
            libc.strtoll.restype, libc.strtod.restype = ctypes.c_longlong, ctypes.c_double
            libc.strtoll.argtypes = [ctypes.c_char_p, ctypes.POINTER(ctypes.c_void_p), ctypes.c_int]
            libc.strtod.argtypes = [ctypes.c_char_p, ctypes.POINTER(ctypes.c_void_p)]
            _LIBC = (ctypes, libc)
        except (OSError, AttributeError):
            _LIBC = False
    return _LIBC


_LIBC = None


def _c_parse(value: str, call):
    """Run strtoll/strtod on ``value`` as rcl does: the number if it takes the whole text without a range
    error (errno), else None."""
    ctypes, libc = _libc()
    raw = value.encode()
    if b"\0" in raw:
        return None
    buffer = ctypes.create_string_buffer(raw)
    end = ctypes.c_void_p()
    ctypes.set_errno(0)
    number = call(libc, buffer, ctypes.byref(end))
    if ctypes.get_errno() != 0 or end.value is None or end.value - ctypes.addressof(buffer) != len(raw):
        return None
    return number


def _c_strtol(value: str):
    if _libc():
        return _c_parse(value, lambda libc, text, end: libc.strtoll(text, end, 0))
    match = re.fullmatch(r"\s*([+-]?)(0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)", value)   # no C library: the same rules
    if not match:
        return None
    digits = match.group(2)
    number = int(digits, 16 if digits[:2].lower() == "0x" else 8 if digits.startswith("0") else 10)
    number = -number if match.group(1) == "-" else number
    return number if -2 ** 63 <= number < 2 ** 63 else None


def _c_strtod(value: str):
    if _libc():
        return _c_parse(value, lambda libc, text, end: libc.strtod(text, end))
    if not re.fullmatch(r"\s*[+-]?((\d+\.?\d*|\.\d+)([eE][+-]?\d+)?|inf(inity)?|nan)", value, re.IGNORECASE):
        return None
    number = float(value)
    return number if math.isnan(number) or (math.isinf(number) == ("inf" in value.lower())
                                             and (number == 0 or abs(number) >= sys.float_info.min)) else None


def _described(value, kind=None) -> str:
    kind = kind or {bool: "bool", int: "integer", float: "double", str: "string"}.get(type(value))
    if value is None:
        return "null"
    if kind == "bool":
        return f"the boolean {str(value).lower()}"
    if kind == "integer":
        return f"the integer {_show(value)}"
    if kind == "double":
        return f"the number {value!r}"
    if kind == "string":
        return f"the string {_show(value)}"
    return f"a {type(value).__name__} ({_show(value)})"


def _show(value, limit: int = 60) -> str:
    """repr of a value for a one-line message, cut to ``limit`` characters."""
    text = repr(value) if not isinstance(value, int) or value.bit_length() < 100 else \
        f"an integer of {value.bit_length()} bits"
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _printable(text, limit: int = 300) -> str:
    """``text`` on one line: control characters escaped, cut to ``limit`` characters."""
    text = "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(text))
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _key_name(path) -> str:
    """The key a path of YAML keys names, as messages name it: 'curve.a' in the shared section, '/x/plant.gain'
    in a node's, list items as [i]."""
    if not path:
        return ""
    section, rest = str(path[0]), [str(part) for part in path[1:]]
    if rest and rest[0] == ROS_PARAMETERS:
        rest = rest[1:]
    parts = [] if section == GLOBAL_SECTION and rest else [section]
    for part in rest:
        parts.append(part if not parts or not part.startswith("[") else parts.pop() + part)
    return _printable(".".join(parts), 80)


def _fail(where: str, key: str, message: str):
    where, key, message = _printable(where), _printable(key, 80), _printable(message, 400)
    raise ConfigError(f"{where}: {key}: {message}" if key else f"{where}: {message}")


def _value(where, key, spec: Param, value):
    """Check one value against its spec and return it normalised."""
    kind = spec.kind
    if kind in ("float", "int", "floats") and isinstance(value, int) and not isinstance(value, bool) and \
            value.bit_length() > 63:
        _fail(where, key, f"expected a value from {(spec.bounds or DEFAULT_BOUNDS[kind])[0]:g} to "
                          f"{(spec.bounds or DEFAULT_BOUNDS[kind])[1]:g}, got {_show(value)}")
    if kind == "float":
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            _fail(where, key, f"expected a number, got {_show(value)}")
        value = float(value)
    elif kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            _fail(where, key, f"expected an integer, got {_show(value)}")
    elif kind == "bool":
        if not isinstance(value, bool):
            _fail(where, key, f"expected true or false, got {_show(value)}")
    elif kind == "str":
        if not isinstance(value, str):
            _fail(where, key, f"expected a string, got {_show(value)}")
        _check_text(where, key, value)
        if spec.choices is not None and value not in spec.choices:
            _fail(where, key, f"expected one of {', '.join(spec.choices)}, got {_show(value)}")
    elif kind == "floats":
        if not isinstance(value, (list, tuple)) or not value or any(
                isinstance(v, bool) or not isinstance(v, (int, float)) for v in value):
            _fail(where, key, f"expected a list of numbers, got {_show(value)}")
        if len(value) > MAX_ITEMS:
            _fail(where, key, f"expected at most {MAX_ITEMS} items, got {len(value)}")
        for index, v in enumerate(value):
            if isinstance(v, int) and v.bit_length() > 63:
                _fail(where, key, f"item {index + 1}: expected a number from {(spec.bounds or DEFAULT_BOUNDS[kind])[0]:g}"
                                  f" to {(spec.bounds or DEFAULT_BOUNDS[kind])[1]:g}, got {_show(v)}")
        value = [float(v) for v in value]
    elif kind == "strings":
        if not isinstance(value, (list, tuple)) or not value or any(not isinstance(v, str) for v in value):
            _fail(where, key, f"expected a non-empty list of names, got {_show(value)}")
        if len(value) > MAX_ITEMS:
            _fail(where, key, f"expected at most {MAX_ITEMS} items, got {len(value)}")
        for v in value:
            _check_text(where, key, v)
        value = list(value)
    elif kind == "dict":
        if not isinstance(value, dict):
            _fail(where, key, f"expected a mapping, got {_show(value)}")
        if spec.choices is not None:
            value = _typed(where, key, "type", spec.choices, value)
    if spec.check == "positive" and not value > 0:
        _fail(where, key, f"expected a positive value, got {_show(value)}")
    if spec.check == "nonnegative" and not value >= 0:
        _fail(where, key, f"expected a value >= 0, got {_show(value)}")
    if kind in ("float", "floats") and not np.all(np.isfinite(value)):
        _fail(where, key, f"expected finite numbers, got {_show(value)}")
    if kind in NUMERIC_KINDS:
        _check_bounds(where, key, spec, value)
    return value


def _check_bounds(where, key, spec: Param, value):
    """Every number of ``value`` within the spec's bounds (or its kind's), and no float denormal."""
    low, high = spec.bounds or DEFAULT_BOUNDS[spec.kind]
    for index, number in enumerate(value if spec.kind == "floats" else [value]):
        item = f"item {index + 1} " if spec.kind == "floats" else ""
        if spec.kind != "int" and number != 0 and abs(number) < sys.float_info.min:
            _fail(where, key, f"{item}{number!r} is a denormal number (below {sys.float_info.min:.3g} in size)")
        if not low <= number <= high:
            _fail(where, key, f"{item}expected a value from {low:g} to {high:g}, got {_show(number)}")


def _check_text(where, key, text: str):
    """A string value: at most MAX_TEXT characters, no control characters (NUL, newlines ...)."""
    if len(text) > MAX_TEXT:
        _fail(where, key, f"expected at most {MAX_TEXT} characters, got {len(text)}")
    if not text.isprintable():
        _fail(where, key, f"control characters (NUL, line breaks ...) are not allowed, got {_show(text)}")


# keys renamed between versions: old name -> (new name, what changed); an experiment file that still uses the
# old name is told the new one (where the section has it) instead of "unknown key"
RENAMED_KEYS = {
    "iterations": ("max_iterations", "the Newton estimator iterates each step until it is within `tolerance`, "
                                     "at most max_iterations times"),
}


def _mapping(where, prefix, specs: dict, given: dict, skip=()) -> dict:
    """Validate a mapping against ``specs``: unknown keys, missing required keys, each value."""
    out = {}
    for key in given:
        if key not in specs and key not in skip:
            renamed = RENAMED_KEYS.get(key)
            if renamed is not None and renamed[0] in specs:
                _fail(where, f"{prefix}{key}", f"`{key}` is now `{renamed[0]}` ({renamed[1]}): rename the key")
            known = ", ".join(sorted(specs)) or "none"
            _fail(where, f"{prefix}{key}", f"unknown key (expected one of: {known})")
    for key, spec in specs.items():
        if key in given:
            out[key] = _value(where, f"{prefix}{key}", spec, given[key])
        elif spec.default is REQUIRED:
            _fail(where, f"{prefix}{key}", "missing required key")
        else:
            out[key] = spec.default if spec.kind != "dict" or spec.choices is None else \
                _typed(where, f"{prefix}{key}", "type", spec.choices, dict(spec.default))
    return out


def _typed(where, prefix, type_key, registry: dict, given: dict) -> dict:
    """Validate a section that names its implementation with ``type_key`` (type, law, model)."""
    name = given.get(type_key)
    if name is None:
        _fail(where, f"{prefix}.{type_key}", f"missing required key (one of: {', '.join(registry)})")
    if name not in registry:
        _fail(where, f"{prefix}.{type_key}", f"unknown name {name!r} (expected one of: {', '.join(registry)})")
    out = _mapping(where, f"{prefix}.", registry[name], given, skip=(type_key,))
    out[type_key] = name
    return out


def _ros_parameters(where, node: str, body) -> dict:
    if not isinstance(body, dict) or set(body) != {ROS_PARAMETERS} or not isinstance(body[ROS_PARAMETERS], dict):
        _fail(where, node, f"expected a mapping with the single key '{ROS_PARAMETERS}'")
    return body[ROS_PARAMETERS]


def node_sections(axes) -> dict:
    """Node name -> role for the graph of ``axes`` (the fully qualified names used in experiment files)."""
    sections = {f"/{axis}/plant": "plant" for axis in axes}
    sections.update({f"/{axis}/servo": "servo" for axis in axes})
    sections.update({"/contour_estimator": "contour_estimator", "/ccc": "ccc"})
    sections.update({f"/{name}": name for name in OPTIONAL_NODES})
    return sections


def split_groups(text: str) -> list:
    """The groups of the ``groups`` key: "x/plant,x/servo; y/plant,y/servo" -> ["x/plant,x/servo", ...]."""
    return [group.strip() for group in text.split(";") if group.strip()]


def _validate_layout(where, out: dict):
    """``layout`` and ``groups`` agree, and every group names nodes of the graph, each once."""
    if out["layout"] == "grouped":
        if not split_groups(out["groups"]):
            _fail(where, "groups", "layout grouped needs its groups, e.g. 'x/plant,x/servo; y/plant,y/servo'")
        try:
            graph.parse_groups(split_groups(out["groups"]), out["axes"], source="groups")
        except ConfigError as error:
            raise ConfigError(f"{_printable(where)}: {error}") from None
    elif out["groups"].strip():
        _fail(where, "groups", f"groups are the grouped layout's: give them with layout: grouped (layout is "
                               f"{out['layout']})")


def _check_curve_points(where, section: dict, curve) -> None:
    """Each point of a curve section (``center``, ``start``, ``end``) has one coordinate per dimension of the
    curve, and the curve evaluates at its start, middle and end to finite points of that dimension (a circle
    whose centre has 3 coordinates on a planar curve failed in every node, at its first step)."""
    dimension = curve.dimension
    for key in ("center", "start", "end"):
        value = section.get(key)
        if section["type"] != "gcode" and isinstance(value, (list, tuple)) and len(value) != dimension:
            _fail(where, f"curve.{key}", f"expected {dimension} coordinates (the {section['type']} curve is "
                                         f"{dimension}-dimensional), got {len(value)}")
    low, high = curve.domain
    try:
        for theta in (low, 0.5 * (low + high), high):
            values = np.asarray(curve.derivatives(float(theta), 3), dtype=float)
            if values.shape != (4, dimension) or not np.all(np.isfinite(values)):
                raise ValueError(f"at theta = {theta:g} it gives {values.shape[-1] if values.ndim else 0} "
                                 f"coordinates{'' if np.all(np.isfinite(values)) else ', not all finite'}, "
                                 f"expected {dimension}")
    except (ArithmeticError, ValueError, TypeError, IndexError) as error:
        _fail(where, "curve", f"cannot evaluate the curve ({type(error).__name__}: {error})")


def _validate_globals(where, given: dict) -> dict:
    out = _mapping(where, "", GLOBALS, given)
    axes = out["axes"]
    for axis in axes:
        if not _AXIS_NAME.match(axis) or "__" in axis or axis in RESERVED_AXIS_NAMES:
            _fail(where, "axes", f"axis name {_show(axis)} must be 1 to 32 ASCII letters, digits and single _, "
                                 "starting with a letter (it becomes a ROS namespace), and not one of "
                                 f"{', '.join(sorted(RESERVED_AXIS_NAMES))}")
    if len(set(axes)) != len(axes):
        _fail(where, "axes", f"axis names must be unique, got {_show(axes)}")
    _validate_layout(where, out)
    name = out["experiment"].get("name")
    if name is not None and (not isinstance(name, str) or not _EXPERIMENT_NAME.match(name) or ".." in name):
        _fail(where, "experiment.name", f"expected 1 to 100 ASCII letters, digits, '_', '-' and '.' (no '/' "
                                        f"or '..': it names the bag file), got {_show(name)}")
    try:
        curve = build_curve_from(out["curve"], where)
        dimension = curve.dimension
        if out["curve"]["type"] == "gcode":
            out["curve"]["file"] = curve.source      # absolute: every node reads the same file
    except (ArithmeticError, ValueError, MemoryError, np.linalg.LinAlgError) as error:
        _fail(where, "curve", f"cannot build the curve ({type(error).__name__}: {error})")
    _check_curve_points(where, out["curve"], curve)
    if dimension != len(axes):
        _fail(where, "axes", f"{len(axes)} axes given but the {out['curve']['type']} curve has {dimension} "
                             "coordinates")
    if len(out["in_position"]) not in (1, len(axes)):
        _fail(where, "in_position", f"expected 1 value or one per axis ({len(axes)}), got {len(out['in_position'])}")
    if out["duration"] == 0.0:
        try:
            schedule = build_schedule_from(out["schedule"], curve, where)
            # with in-position checks every exact stop may wait up to its timeout
            waits = len(schedule.stops) * out["schedule"]["in_position_timeout"] \
                if in_position_windows(out) is not None and hasattr(schedule, "stops") else 0.0
            out["duration"] = schedule.duration + waits + out["settle_time"]
        except (ArithmeticError, ValueError, MemoryError, np.linalg.LinAlgError) as error:
            _fail(where, "schedule", f"cannot build the schedule ({type(error).__name__}: {error})")
        if not out["duration"] <= MAX_DURATION:
            hint = "; check the part program's units (G20 inch, G21 mm) and feeds (F is per minute)" \
                if out["curve"]["type"] in ("gcode", "toolpath") else ""
            _fail(where, "schedule", f"the schedule and settle_time take {_show(out['duration'])} s; at most "
                                     f"{MAX_DURATION:g} s of simulated time{hint}")
    if out["sample_time"] > out["duration"]:
        _fail(where, "sample_time", f"expected at most the duration ({out['duration']} s)")
    steps = out["duration"] / out["sample_time"] + 1
    if not steps <= MAX_STEPS:
        _fail(where, "duration", f"{out['duration']:g} s at a sample_time of {out['sample_time']:g} s is "
                                 f"{steps:.3g} steps; at most {MAX_STEPS:.0e}")
    return out


def _validate_role(where, node: str, role: str, given: dict, globals_: dict) -> dict:
    if role in OPTIONAL_NODES:
        return _mapping(where, f"{node}.", OPTIONAL_NODES[role], given)
    type_key, registry = ROLE_TYPES[role]
    section = _typed(where, node, type_key, registry, given)
    _check_entry(where, node, registry.entry(section[type_key]), section, tuple(globals_["axes"]))
    return section


def _check_entry(where, node: str, entry, section: dict, axes: tuple):
    """The type's own constraint on its section (the registry entry's ``check``), as a one-line error."""
    problem = entry.check(section, axes) if entry.check is not None else None
    if problem:
        key, message = problem
        _fail(where, f"{node}.{key}", message)


def _validate_combination(where, estimator: dict, controller: dict, servos: dict):
    """Refuse estimator / controller / servo combinations whose maths does not fit together."""
    entry = CONTROLLERS.entry(controller["type"])
    whole = entry.whole_command
    for axis, section in servos.items():
        direct = SERVOS.entry(section["law"]).direct
        if whole and not direct:
            laws = " or ".join(repr(name) for name, e in SERVOS._entries.items() if e.direct)
            _fail(where, f"/{axis}/servo.law", f"the {controller['type']} controller computes the whole command: "
                                               f"every servo law must be {laws}")
        if not whole and direct:
            _fail(where, f"/{axis}/servo.law", f"{section['law']!r} passes the contour controller's output through, "
                                               f"but the {controller['type']} controller only adds corrections: the "
                                               "axis would run open loop")
    problem = entry.combination(estimator, controller, servos) if entry.combination is not None else None
    if problem:
        key, message = problem
        _fail(where, key, message)


def parse_experiment(text: str, where: str = "<experiment>", ros: bool = False) -> Experiment:
    """Validate the YAML ``text`` of an experiment; ``where`` names it in errors; ``ros``: also refuse what
    the ROS 2 parameter parser would read differently (see :func:`read_yaml`)."""
    return experiment_from_data(read_yaml(text, where, ros), where, text)


def read_yaml(text: str, where: str = "<experiment>", ros: bool = False):
    """The data of an experiment's YAML ``text`` (aliases and explicit tags refused, nesting at most
    MAX_DEPTH levels, exponent floats read as numbers).

    ``ros``: the text is a parameter file the nodes will read (load_experiment): refuse every value that the
    ROS 2 parameter parser reads differently or refuses (_NoAliasLoader.check_ros), naming its key.
    """
    where = _printable(where)
    if len(text) > MAX_FILE_BYTES:
        raise ConfigError(f"{where}: too large ({len(text)} characters; an experiment is at most "
                          f"{MAX_FILE_BYTES} bytes)")
    deep = _too_deep_flow(text)
    if deep is not None:      # [[[[... (libyaml's time grows with the square of the depth): name the key from
        text = text[:deep + 1]     # the text up to the bracket too deep, which the loader refuses at once
    loader = _NoAliasLoader(text)
    try:
        events = _CParser(text).raw_parse() if _CParser is not None and deep is None else 0   # counted in C
        if events > MAX_EVENTS:
            raise ConfigError(f"more than {MAX_EVENTS} YAML values and collections ({events} parser events); an "
                              "experiment has a few hundred")
        node = loader.get_single_node()
        if node is not None and ros:
            loader.check_ros(node)
        data = loader.construct_document(node) if node is not None else None
    except ConfigError as error:
        raise ConfigError(f"{where}: {_printable(error, 400)}") from None
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        line = f"line {mark.line + 1}: " if mark is not None else ""
        problem = getattr(error, "problem", None) or str(error).splitlines()[0]
        key = _key_name(getattr(loader, "_path", []))
        raise ConfigError(f"{where}: {key + ': ' if key else ''}{line}not valid YAML ({_printable(problem, 200)})") \
            from None
    except RecursionError:
        raise ConfigError(f"{where}: nested too deeply (at most {MAX_DEPTH} levels)") from None
    except (ValueError, OverflowError) as error:     # e.g. an integer of more than 4300 digits
        key = _key_name(getattr(loader, "_path", []))
        raise ConfigError(f"{where}: {key + ': ' if key else ''}cannot read a value "
                          f"({_printable(error, 200)})") from None
    finally:
        loader.dispose()
    if deep is not None:
        raise ConfigError(f"{where}: line {text.count(chr(10)) + 1}: nested deeper than {MAX_DEPTH} levels")
    return data


_QUOTED_OR_COMMENT = re.compile(r'"(?:[^"\\\n]|\\.)*"|\'(?:[^\'\n]|\'\')*\'|(?:^|(?<=\s))#[^\n]*', re.MULTILINE)


def _too_deep_flow(text: str):
    """Where the flow collections ([...], {...}) of ``text`` first nest deeper than MAX_DEPTH (quoted strings
    and comments aside), or None."""
    if text.count("[") + text.count("{") <= MAX_DEPTH:
        return None
    blank = _QUOTED_OR_COMMENT.sub(lambda match: re.sub(r"[^\n]", " ", match.group()), text)
    depth = 0
    for match in re.finditer(r"[\[\]{}]", blank):
        depth += 1 if match.group() in "[{" else -1
        if depth > MAX_DEPTH:
            return match.start()
    return None


def experiment_from_data(data, where: str = "<experiment>", text: str = "") -> Experiment:
    """Validate an experiment already read from YAML (``text``, if given, is kept as its source)."""
    if not isinstance(data, dict) or not data:
        _fail(where, "", "expected a ROS 2 parameter file (a mapping of node names to ros__parameters)")
    if GLOBAL_SECTION not in data:
        _fail(where, GLOBAL_SECTION, "missing required section with the shared keys")
    globals_ = _validate_globals(where, _ros_parameters(where, GLOBAL_SECTION, data[GLOBAL_SECTION]))
    sections = node_sections(globals_["axes"])
    parsed = {}
    for node, body in data.items():
        if node == GLOBAL_SECTION:
            continue
        if node not in sections:
            _fail(where, str(node), f"unknown node section (expected one of: {', '.join(sections)})")
        parsed[node] = _validate_role(where, node, sections[node], _ros_parameters(where, node, body), globals_)
    for node, role in sections.items():
        if node not in parsed and role not in OPTIONAL_NODES:
            _fail(where, node, "missing required node section")
    axes = globals_["axes"]
    _validate_combination(where, parsed["/contour_estimator"], parsed["/ccc"],
                          {a: parsed[f"/{a}/servo"] for a in axes})
    experiment = Experiment(
        path=where, text=text, **_shared_fields(globals_),
        plants={a: parsed[f"/{a}/plant"] for a in axes}, servos={a: parsed[f"/{a}/servo"] for a in axes},
        estimator=parsed["/contour_estimator"], controller=parsed["/ccc"],
        info={"experiment": globals_["experiment"], "paper": globals_["paper"]})
    if not experiment.ccc_takes_state:
        check_ccc_takes_state(where, experiment, controller_uses_state(experiment))
    return experiment


def _shared_fields(globals_: dict) -> dict:
    """The Experiment fields the shared keys (/**) give, by name: every field of Experiment named in GLOBALS
    (axes as a tuple), so that a new shared key reaches the Experiment of a file and of a node alike."""
    out = {f.name: globals_[f.name] for f in fields(Experiment) if f.name in GLOBALS}
    out["axes"] = tuple(out["axes"])
    out["in_position"] = tuple(out["in_position"])
    return out


def experiment_for_node(parameters: dict, node: str, role: str, where: str | None = None) -> Experiment:
    """Validate the parameters one node received (shared keys and its own section) like a file would be.

    ``parameters`` maps flat ROS parameter names to values; the other nodes' sections stay empty.
    """
    where = where or f"node {node}"
    nested = section_from_parameters({k: v for k, v in parameters.items() if k not in ROS_BUILTIN_PARAMETERS})
    globals_ = _validate_globals(where, {k: v for k, v in nested.items() if k in GLOBALS})
    own = {k: v for k, v in nested.items() if k not in GLOBALS}
    try:
        section = _validate_role(where, node, role, own, globals_)
    except ConfigError as error:
        namespace = graph_namespace(node, role in ("plant", "servo"))
        if namespace == "/" or "missing required key" not in str(error):
            raise
        plain = node[len(namespace):]
        raise ConfigError(f"{error} (hint: this node runs under the namespace {namespace}, and the ROS parameter "
                          f"parser gives it the file's section \"{node}\" only: a file whose sections name {plain} "
                          f"fits the graph without a namespace; write the sections with it, e.g. with "
                          f"contouring_ros.config.namespaced_parameter_file(text, \"{namespace}\"), as contouring-ros "
                          f"run --namespace does)") from None
    parts = node.strip("/").split("/")
    axis = parts[-2] if len(parts) > 1 else ""       # a per-axis node's namespace ends in its axis
    return Experiment(
        path=where, text="", **_shared_fields(globals_),
        plants={axis: section} if role == "plant" else {}, servos={axis: section} if role == "servo" else {},
        estimator=section if role == "contour_estimator" else {}, controller=section if role == "ccc" else {},
        info={"experiment": globals_["experiment"], "paper": globals_["paper"], "node": section})


def check_ccc_takes_state(where: str, experiment: Experiment, uses_state: bool):
    """Refuse ``ccc_takes_state: false`` for a controller that uses the reference and the axis states (the
    file's check, and the CCC node's own for nodes started by hand)."""
    if uses_state and not experiment.ccc_takes_state:
        _fail(where, f"{GLOBAL_SECTION}.ccc_takes_state", f"the {experiment.controller['type']} controller uses the "
              "reference and the axis states: the CCC must take them (true)")


def controller_uses_state(experiment: Experiment) -> bool:
    """Whether the experiment's contour controller uses the reference and the axis states (``needs_state``),
    i.e. whether the CCC node must take them (the shared key ``ccc_takes_state``)."""
    return bool(getattr(build_controller(experiment, build_curve(experiment)), "needs_state", False))


def namespaced_parameter_file(text: str, namespace: str) -> str:
    """The experiment file ``text`` for nodes started under the graph ``namespace``: each node section's
    key gets the namespace in front (/x/plant: becomes "/m1/x/plant":, which the ROS parameter parser
    matches with the node's fully qualified name); the shared section /** and every value stay as
    written, byte for byte (only the keys' text is replaced, at the positions the YAML parser gives)."""
    if namespace in ("", "/"):
        return text
    root = yaml.compose(text, Loader=yaml.SafeLoader)
    if not isinstance(root, yaml.MappingNode):
        return text
    out = text
    for key, _ in sorted(root.value, key=lambda pair: pair[0].start_mark.index, reverse=True):
        if isinstance(key, yaml.ScalarNode) and key.value.startswith("/") and key.value != GLOBAL_SECTION:
            start, end = key.start_mark.index, key.end_mark.index
            out = out[:start] + f'"{graph.resolve(namespace, key.value)}"' + out[end:]
    return out


def load_experiment(path) -> Experiment:
    """Read and validate an experiment file: a regular file of at most MAX_FILE_BYTES of UTF-8 text without
    NUL, whose values the ROS 2 parameter parser reads as this validator does (the nodes read the same
    file). Every problem is a ConfigError of one line naming the file and the key."""
    path = Path(path)
    where = _printable(path)
    raw = _read_file(path, where)
    if not raw.strip():
        raise ConfigError(f"{where}: the file is empty")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as error:
        raise ConfigError(f"{where}: not a text file (not UTF-8 at byte {error.start})") from None
    if "\x00" in text:
        raise ConfigError(f"{where}: not a text file (contains NUL bytes)")
    data = read_yaml(text, where, ros=True)
    experiment = experiment_from_data(data, where, text)
    if experiment.curve["type"] == "gcode":
        given = data[GLOBAL_SECTION][ROS_PARAMETERS]["curve"]["file"]
        experiment = replace(experiment, text=_program_path_in_text(text, given, experiment.curve["file"]))
    return experiment


def recorded_text(path) -> str:
    """The text a bag keeps of the experiment file ``path``: the file's own, with a part program's relative
    ``file`` made absolute (see :func:`load_experiment`)."""
    text = Path(path).read_text()
    try:
        experiment = load_experiment(path)
    except ConfigError:
        return text
    return experiment.text if experiment.curve["type"] == "gcode" else text


def _program_path_in_text(text: str, given: str, resolved: str) -> str:
    """The experiment's YAML with its part program's ``file`` made the absolute path it was resolved to, so
    the text stands alone where it is kept (bags, sweeps); unchanged where the value is absolute already or
    does not appear exactly once."""
    if given == resolved:
        return text
    pattern = re.compile(r"(\bfile:\s*)([\"']?)" + re.escape(given) + r"\2(?=\s*[,}\n]|\s*$)")
    if len(pattern.findall(text)) != 1:
        return text
    quoted = '"' + resolved.replace("\\", "\\\\").replace('"', '\\"') + '"'
    return pattern.sub(lambda match: match.group(1) + quoted, text)


def _read_file(path: Path, where: str, limit: int = MAX_FILE_BYTES,
               what: str = "an experiment is a YAML file") -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes (an experiment's MAX_FILE_BYTES, a part
    program's MAX_PROGRAM_BYTES); FIFOs, devices, sockets and directories are refused before they are
    opened (a FIFO would block, /dev/zero never end)."""
    try:
        info = path.stat()
    except (OSError, ValueError) as error:   # ValueError: a NUL in the path
        raise ConfigError(f"{where}: cannot read ({getattr(error, 'strerror', None) or error})") from None
    kinds = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"),
             (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))
    for test, kind in kinds:
        if test(info.st_mode):
            raise ConfigError(f"{where}: not a regular file ({kind}); {what}")
    if not stat.S_ISREG(info.st_mode):
        raise ConfigError(f"{where}: not a regular file; {what}")
    if info.st_size > limit:
        raise ConfigError(f"{where}: too large ({info.st_size} bytes; {what.split(' is ')[0]} is at most {limit})")
    try:   # O_NONBLOCK: should the path have become a FIFO since, opening it does not wait for a writer
        descriptor = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except OSError as error:
        raise ConfigError(f"{where}: cannot read ({error.strerror})") from None
    with os.fdopen(descriptor, "rb") as stream:
        if not stat.S_ISREG(os.fstat(stream.fileno()).st_mode):
            raise ConfigError(f"{where}: not a regular file; {what}")
        try:
            raw = stream.read(limit + 1)
        except OSError as error:
            raise ConfigError(f"{where}: cannot read ({error.strerror})") from None
    if len(raw) > limit:
        raise ConfigError(f"{where}: too large (more than {limit} bytes)")
    return raw


def section_from_parameters(parameters: dict) -> dict:
    """Nest flat ROS parameter names ('curve.type') back into the mapping the file had."""
    nested: dict = {}
    for name, value in parameters.items():
        node = nested
        *parents, leaf = name.split(".")
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = list(value) if isinstance(value, (list, tuple)) or hasattr(value, "tolist") else value
    return nested


# --- building core objects ---------------------------------------------------------------------------

def _kwargs(section: dict, type_key: str = "type") -> dict:
    return {k: v for k, v in section.items() if k != type_key}


def build_curve_from(section: dict, where: str = "curve") -> curves.Curve:
    try:
        curve = CURVES.build(section, BuildContext(where=where))
    except ValueError as error:
        raise ConfigError(f"{where}: curve: {error}") from None
    curve.contour_error_window = section["contour_error_window"]
    return curve


def build_curve(experiment: Experiment) -> curves.Curve:
    return build_curve_from(experiment.curve, experiment.path)


def build_schedule_from(section: dict, curve, where: str = "schedule"):
    return SCHEDULES.build(section, BuildContext(curve=curve, where=where))


def build_schedule(experiment: Experiment, curve=None):
    return build_schedule_from(experiment.schedule, curve or build_curve(experiment), experiment.path)


BuildContext.schedule_builder = build_schedule


def build_disturbance(section: dict):
    return DISTURBANCES.build(section, BuildContext())


def initial_state(experiment: Experiment, curve=None, schedule=None):
    """Initial axis positions, velocities and accelerations: on the reference at t = 0, moving with it
    (``on_reference``) or at rest (``at_rest``)."""
    curve = curve or build_curve(experiment)
    schedule = schedule or build_schedule(experiment, curve)
    start = reference(curve, schedule, 0.0)
    if experiment.initial_state == "on_reference":
        return start.position, start.velocity, start.acceleration
    return start.position, np.zeros_like(start.velocity), np.zeros_like(start.acceleration)


def build_plant(experiment: Experiment, axis: str, position: float, velocity: float):
    return PLANTS.build(experiment.plants[axis], BuildContext(experiment, axis=axis, position=position,
                                                              velocity=velocity, where=experiment.path))


def in_position_windows(shared) -> list | None:
    """Each axis' in-position window [m] (the shared key ``in_position``, an Experiment or the shared
    section) where the reference waits at exact stops for the axes: a tool path planned by the jerk-limited
    feed plan with a window > 0; else None (the reference runs on the plan's own time and the interpolator
    takes no axis state)."""
    get = shared.get if isinstance(shared, dict) else lambda key: getattr(shared, key)
    curve, schedule = get("curve"), get("schedule")
    planned = curve["type"] == "gcode" or (curve["type"] == "toolpath" and schedule["type"] == "feedrate"
                                           and schedule.get("jerk"))
    windows = [float(w) for w in get("in_position")]
    if not planned or not any(windows):
        return None
    return windows * len(get("axes")) if len(windows) == 1 else windows


def build_clock(experiment: Experiment, curve, schedule):
    """The reference's :class:`~contouring_ros.core.interpolation.InPositionClock`, or None (see
    :func:`in_position_windows`)."""
    windows = in_position_windows(experiment)
    if windows is None or not hasattr(schedule, "stops"):
        return None
    return InPositionClock(schedule, curve, windows, experiment.sample_time,
                           experiment.schedule["in_position_timeout"], LOOKAHEAD)


def build_servo(experiment: Experiment, axis: str, position: float, velocity: float, acceleration: float):
    return SERVOS.build(experiment.servos[axis], BuildContext(experiment, axis=axis, position=position,
                                                              velocity=velocity, acceleration=acceleration,
                                                              where=experiment.path))


def build_estimator(experiment: Experiment, curve):
    return ESTIMATORS.build(experiment.estimator, BuildContext(experiment, curve, where=experiment.path))


def build_controller(experiment: Experiment, curve):
    return CONTROLLERS.build(experiment.controller, BuildContext(experiment, curve, where=experiment.path))


def build_loop(experiment: Experiment) -> ControlLoop:
    """Every core object of the experiment, in their initial state."""
    curve = build_curve(experiment)
    schedule = build_schedule(experiment, curve)
    positions, velocities, accelerations = initial_state(experiment, curve, schedule)
    axes = experiment.axes
    return ControlLoop(
        curve=curve, schedule=schedule, clock=build_clock(experiment, curve, schedule),
        plants=[build_plant(experiment, a, positions[i], velocities[i]) for i, a in enumerate(axes)],
        servos=[build_servo(experiment, a, positions[i], velocities[i], accelerations[i])
                for i, a in enumerate(axes)],
        estimator=build_estimator(experiment, curve), controller=build_controller(experiment, curve),
        sample_time=experiment.sample_time, n_steps=experiment.n_steps,
        divergence_factor=experiment.divergence_factor)
