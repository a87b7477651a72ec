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
import re
import sys
from dataclasses import fields, replace
from pathlib import Path

import numpy as np
import yaml

from . import graph
from .core import contouring, curves, disturbances, estimators, gcode, plants, servo
from .core.feed_planning import FeedPlan
from .core.interpolation import FeedrateSchedule, InPositionClock, UniformSchedule, reference
from .core.simulation import ControlLoop
from .errors import ConfigError
from .experiment.model import Experiment
from .experiment.ros_yaml import _PARAMETER_NAME, _read_file, read_yaml
from .experiment.ros_yaml import _ros_scalar as _ros_scalar
from .experiment.scenarios import resolve_part_program
from .experiment.schema import (
    BOUNDS, GLOBAL_SECTION, LIMIT, MAX_DURATION, MAX_PROGRAM_BYTES, MAX_STEPS, NUMERIC_KINDS, ROS_PARAMETERS, Param,
    _fail, _gains, _mapping, _printable, _show, _typed)
# re-exported: where they were defined before contouring_ros.experiment
from .experiment.schema import DEFAULT_BOUNDS as DEFAULT_BOUNDS, MAX_DEPTH as MAX_DEPTH, MAX_EVENTS as MAX_EVENTS
from .experiment.schema import MAX_FILE_BYTES as MAX_FILE_BYTES, MAX_ITEMS as MAX_ITEMS, MAX_TEXT as MAX_TEXT
from .experiment.schema import RENAMED_KEYS as RENAMED_KEYS, REQUIRED as REQUIRED
from .graph import LOOKAHEAD, graph_namespace
from .registry import BuildContext, Role

__all__ = ["Experiment", "load_experiment", "parse_experiment", "read_yaml", "experiment_from_data", "build_loop",
           "build_curve",
           "build_schedule", "build_plant", "build_servo", "build_estimator", "build_controller",
           "initial_state", "controller_uses_state", "check_ccc_takes_state", "GLOBAL_SECTION", "node_sections", "section_from_parameters",
           "experiment_for_node", "namespaced_parameter_file"]

ROS_BUILTIN_PARAMETERS = {"use_sim_time", "start_type_description_service"}  # every rclpy node declares these


                                  # without: DEFAULT_BOUNDS of its kind)


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


#: the curve types that are part programs (tool paths planned block by block)
TOOL_PATH_TYPES = ("gcode", "toolpath")


def plan_correction(section: dict, experiment) -> bool:
    """Whether an ISMC servo's disturbance estimate gets the plan correction: the section's
    ``observer_plan_correction`` where given, else on a tool path only (whose feed plan has jerk phases:
    paper 000's own experiments keep the paper's eq. 25)."""
    given = section["observer_plan_correction"]
    if given is not None:
        return bool(given)
    return experiment is not None and experiment.curve["type"] in TOOL_PATH_TYPES


def _ismc(s, c):
    ts = c.sample_time
    observer = servo.DisturbanceObserver(s["c"], s["d"], s["gain"], s["time_constant"], ts, c.velocity,
                                         c.acceleration, plan_correction(s, c.experiment)) if s["observer"] else None
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
             "observer_plan_correction": Param("bool", None),      # None: true on a tool path, else false
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
}, task_frame_pd={"whole_command": True, "check": _check_task_frame_pd, "combination": _task_frame_estimator,
                  "needs_state": contouring.TaskFramePD.needs_state},
    tvt={"whole_command": True, "needs_state": contouring.TangentialVelocityCCC.needs_state},
    adaptive_tnb={"check": _per_axis("adaptive_tnb", ("coupling", "gamma_mass", "gamma_damping", "mass0",
                                                       "damping0")),
                  "needs_state": contouring.AdaptiveTNBCCC.needs_state})
# built-in controllers that compute every axis' whole command (their servos must be 'direct', and only theirs;
# a plugin says so with whole_command on its entry)
WHOLE_COMMAND_CONTROLLERS = {name for name, entry in CONTROLLERS.registered().items() if entry.whole_command}
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


_AXIS_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,31}$")
_EXPERIMENT_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}$")
RESERVED_AXIS_NAMES = {"theta", "contour_error", "foot_point_parameter"}   # other joint names of the messages


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
                if out["curve"]["type"] in TOOL_PATH_TYPES else ""
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
            laws = " or ".join(repr(name) for name, e in SERVOS.registered().items() if e.direct)
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
    i.e. whether the CCC node must take them (the shared key ``ccc_takes_state``): read from the controller's
    registry entry, nothing is built."""
    return CONTROLLERS.entry(experiment.controller["type"]).needs_state


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
    if "contour_error_window" in section:       # a key of every built-in curve; a plugin's curve keeps its own
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
