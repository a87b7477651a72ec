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

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from .core import contouring, curves, disturbances, estimators, plants, servo
from .core.interpolation import FeedrateSchedule, UniformSchedule, reference
from .core.simulation import ControlLoop
from .errors import ConfigError

__all__ = ["Experiment", "load_experiment", "parse_experiment", "read_yaml", "experiment_from_data", "build_loop",
           "build_curve",
           "build_schedule", "build_plant", "build_servo", "build_estimator", "build_controller",
           "initial_state", "controller_uses_state", "check_ccc_takes_state", "GLOBAL_SECTION", "node_sections", "section_from_parameters",
           "experiment_for_node"]

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


LIMIT = Param("float", 0.0, "nonnegative", help="output limit in command units, 0: none (anti-windup when hit)")


def _gains(**defaults):
    gains = {name: Param("float", defaults.get(name, REQUIRED), "nonnegative") for name in ("kp", "ki", "kd")}
    return {**gains, "output_limit": LIMIT}


TIMINGS = ("lockstep", "realtime")
INVALID_INPUT_POLICIES = ("stop", "hold")
INITIAL_STATES = ("on_reference", "at_rest")
DISTURBANCE_UNITS = ("command", "acceleration")
# task-frame controllers: the local approximation they act on -> the estimator that reports its errors
APPROXIMATIONS = {"first_order": "tangent_line", "natural_local": "natural_local"}

# Registries: type name -> expected parameters. Defaults live here and nowhere else.
DISTURBANCES = {
    "none": {},
    "constant": {"value": Param("float")},
    "sinusoid": {"amplitude": Param("float"), "frequency": Param("float", check="positive"),
                 "phase": Param("float", 0.0), "offset": Param("float", 0.0)},
    "random": {"std": Param("float", check="nonnegative"), "seed": Param("int", 0, "nonnegative"),
               "offset": Param("float", 0.0)},
}
CURVES = {
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
    "helix": {"a": Param("float", check="positive"), "b": Param("float", check="positive"), "c": Param("float"),
              "omega": Param("float"), "length": Param("float", check="positive")},
}
WINDOW = Param("float", 0.0, "nonnegative", help="curve-parameter half-width the exact contour error searches "
                                                "around the reference point; 0: the whole curve")
for _spec in CURVES.values():
    _spec["contour_error_window"] = WINDOW
SCHEDULES = {
    "uniform": {"theta_start": Param("float"), "theta_end": Param("float"),
                "duration": Param("float", check="positive")},
    "feedrate": {"theta_start": Param("float", None), "theta_end": Param("float", None),  # default: the curve's domain
                 "feedrate": Param("float", check="positive"), "acceleration": Param("float", check="positive"),
                 "normal_acceleration": Param("float", 0.0, "nonnegative"),
                 "samples": Param("int", 20001, "positive")},
}
PLANTS = {
    "first_order_velocity": {"gain": Param("float", check="positive"),
                             "time_constant": Param("float", check="positive"),
                             "disturbance": Param("dict", {"type": "none"}, choices=DISTURBANCES),
                             "saturation": LIMIT, "encoder_resolution": Param("float", 0.0, "nonnegative")},
    "mass_damper": {"mass": Param("float", check="positive"), "damping": Param("float", check="nonnegative"),
                    "gain": Param("float", check="positive"),
                    "coulomb_positive": Param("float", 0.0, "nonnegative"),
                    "coulomb_negative": Param("float", 0.0, "nonnegative"),
                    "disturbance": Param("dict", {"type": "none"}, choices=DISTURBANCES),
                    "disturbance_unit": Param("str", "command", choices=DISTURBANCE_UNITS),
                    "saturation": LIMIT, "encoder_resolution": Param("float", 0.0, "nonnegative")},
}
SERVOS = {
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
ESTIMATORS = {
    "tangent_line": {},
    "natural_local": {},
    "osculating_circle": {},
    "foot_point_search": {"max_iterations": Param("int", 10, "positive"),
                          "tolerance": Param("float", 1e-6, "positive")},
    "newton": {"k_prime": Param("float", check="positive"), "c_prime": Param("float", check="positive"),
               "iterations": Param("int", 20, "positive"), "inner_step": Param("float", 0.0, "nonnegative"),
               "theta0": Param("float", None),
               "branch_check_samples": Param("int", 256, "nonnegative"),      # 0: no global check
               "branch_check_tolerance": Param("float", 1e-4, "positive")},   # m
}
CONTROLLERS = {
    "none": {},
    "variable_gain": _gains(),
    "unit_vector": _gains(),
    "task_frame_pd": {"approximation": Param("str", choices=tuple(APPROXIMATIONS)), "mass": Param("floats"), "damping": Param("floats"),
                      "gain": Param("floats"), "coulomb_positive": Param("floats", None),
                      "coulomb_negative": Param("floats", None), "f_t": Param("float", check="positive"),
                      "f_n": Param("float", check="positive"), "f_b": Param("float", None, "positive"),
                      "zeta": Param("float", 1.0, "positive")},
}
CONTROLLERS["tvt"] = {"kc": Param("float", check="nonnegative"),
                      "min_feedrate": Param("float", 1e-3, "nonnegative")}
CONTROLLERS["adaptive_tnb"] = {
    "coupling": Param("floats"), "alpha": Param("float", check="positive"), "gamma_mass": Param("floats"),
    "gamma_damping": Param("floats"), "mass0": Param("floats"), "damping0": Param("floats")}
# controllers that compute every axis' whole command (their servos must be 'direct', and only theirs)
WHOLE_COMMAND_CONTROLLERS = {"task_frame_pd", "tvt"}
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
    "on_invalid_input": Param("str", "stop", choices=INVALID_INPUT_POLICIES),  # what a node does with a
                                                                             # non-finite or malformed input
    "timing": Param("str", "lockstep", choices=TIMINGS),   # DESIGN.md, "One control step"
    "start_time": Param("float", 0.0, "nonnegative"),  # realtime: Unix time of tick 0 (the runner sets it)
    # whether the CCC subscribes to /reference and the states: contouring-ros run sets false where the
    # controller does not use them (3 fewer deliveries a step with 2 axes); true is always safe
    "ccc_takes_state": Param("bool", True),
}
# node section -> (key holding the type name, registry)
ROLE_TYPES = {"plant": ("model", PLANTS), "servo": ("law", SERVOS),
              "contour_estimator": ("type", ESTIMATORS), "ccc": ("type", CONTROLLERS)}
# nodes whose section may be left out, with the keys they take
OPTIONAL_NODES = {"interpolator": {}, "recorder": {"bag": Param("str", ""), "experiment_file": Param("str", "")}}


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
    on_invalid_input: str = "stop"
    timing: str = "lockstep"
    start_time: float = 0.0
    ccc_takes_state: bool = True
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


class _NoAliasLoader(yaml.SafeLoader):
    """YAML loader that refuses anchors/aliases, so no file can expand without bound, and reads every
    exponent float (1e-3, 4.86e7) as a number, as YAML 1.2 and the ROS parameter parser do."""

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise ConfigError(f"line {event.start_mark.line + 1}: YAML aliases (*name) are not allowed "
                              "in experiment files")
        return super().compose_node(parent, index)


_NoAliasLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float", re.compile(r"^[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."))


def _fail(where: str, key: str, message: str):
    raise ConfigError(f"{where}: {key}: {message}" if key else f"{where}: {message}")


def _value(where, key, spec: Param, value):
    """Check one value against its spec and return it normalised."""
    kind = spec.kind
    if kind == "float":
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            _fail(where, key, f"expected a number, got {value!r}")
        value = float(value)
    elif kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            _fail(where, key, f"expected an integer, got {value!r}")
    elif kind == "bool":
        if not isinstance(value, bool):
            _fail(where, key, f"expected true or false, got {value!r}")
    elif kind == "str":
        if not isinstance(value, str):
            _fail(where, key, f"expected a string, got {value!r}")
        if spec.choices is not None and value not in spec.choices:
            _fail(where, key, f"expected one of {', '.join(spec.choices)}, got {value!r}")
    elif kind == "floats":
        if not isinstance(value, (list, tuple)) or not value or any(
                isinstance(v, bool) or not isinstance(v, (int, float)) for v in value):
            _fail(where, key, f"expected a list of numbers, got {value!r}")
        value = [float(v) for v in value]
    elif kind == "strings":
        if not isinstance(value, (list, tuple)) or not value or any(not isinstance(v, str) for v in value):
            _fail(where, key, f"expected a non-empty list of names, got {value!r}")
        value = list(value)
    elif kind == "dict":
        if not isinstance(value, dict):
            _fail(where, key, f"expected a mapping, got {value!r}")
        if spec.choices is not None:
            value = _typed(where, key, "type", spec.choices, value)
    if spec.check == "positive" and not value > 0:
        _fail(where, key, f"expected a positive value, got {value!r}")
    if spec.check == "nonnegative" and not value >= 0:
        _fail(where, key, f"expected a value >= 0, got {value!r}")
    if kind in ("float", "floats") and not np.all(np.isfinite(value)):
        _fail(where, key, f"expected finite numbers, got {value!r}")
    return value


def _mapping(where, prefix, specs: dict, given: dict, skip=()) -> dict:
    """Validate a mapping against ``specs``: unknown keys, missing required keys, each value."""
    out = {}
    for key in given:
        if key not in specs and key not in skip:
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


def _validate_globals(where, given: dict) -> dict:
    out = _mapping(where, "", GLOBALS, given)
    axes = out["axes"]
    for axis in axes:
        if not axis.isidentifier():
            _fail(where, "axes", f"axis name {axis!r} must be a plain identifier (it becomes a namespace)")
    if len(set(axes)) != len(axes):
        _fail(where, "axes", f"axis names must be unique, got {axes}")
    dimension = build_curve_from(out["curve"], where).dimension
    if dimension != len(axes):
        _fail(where, "axes", f"{len(axes)} axes given but the {out['curve']['type']} curve has {dimension} "
                             "coordinates")
    if out["duration"] == 0.0:
        out["duration"] = _schedule_duration(where, out["curve"], out["schedule"]) + out["settle_time"]
    if out["sample_time"] > out["duration"]:
        _fail(where, "sample_time", f"expected at most the duration ({out['duration']} s)")
    return out


def _validate_role(where, node: str, role: str, given: dict, globals_: dict) -> dict:
    if role in OPTIONAL_NODES:
        return _mapping(where, f"{node}.", OPTIONAL_NODES[role], given)
    type_key, registry = ROLE_TYPES[role]
    section = _typed(where, node, type_key, registry, given)
    if role == "contour_estimator" and section["type"] == "osculating_circle" and len(globals_["axes"]) != 2:
        _fail(where, f"{node}.type", "the osculating_circle estimate needs a planar contour (2 axes)")
    if role == "servo" and section["law"] == "eso_smc" and len(section["alphas"]) != 3:
        _fail(where, f"{node}.alphas", f"expected the three ESO gains alpha_1..3, got {len(section['alphas'])}")
    if role == "ccc" and section["type"] == "task_frame_pd":
        if len(globals_["axes"]) == 3 and section["f_b"] is None:
            _fail(where, f"{node}.f_b", "missing required key (the binormal bandwidth, for 3 axes)")
    per_axis_keys = {"task_frame_pd": ("mass", "damping", "gain", "coulomb_positive", "coulomb_negative"),
                     "adaptive_tnb": ("coupling", "gamma_mass", "gamma_damping", "mass0", "damping0")}
    if role == "ccc" and section["type"] in per_axis_keys:
        if len(globals_["axes"]) not in (2, 3):
            _fail(where, f"{node}.type", f"the {section['type']} controller needs 2 or 3 axes (a Frenet frame)")
        for key in per_axis_keys[section["type"]]:
            if section[key] is not None and len(section[key]) != len(globals_["axes"]):
                _fail(where, f"{node}.{key}", f"expected one value per axis ({len(globals_['axes'])}), "
                                              f"got {len(section[key])}")
    return section


def _validate_combination(where, estimator: dict, controller: dict, servos: dict):
    """Refuse estimator / controller / servo combinations whose maths does not fit together."""
    whole = controller["type"] in WHOLE_COMMAND_CONTROLLERS
    for axis, section in servos.items():
        if whole and section["law"] != "direct":
            _fail(where, f"/{axis}/servo.law", f"the {controller['type']} controller computes the whole command: "
                                               "every servo law must be 'direct'")
        if not whole and section["law"] == "direct":
            _fail(where, f"/{axis}/servo.law", f"'direct' passes the contour controller's output through, but the "
                                               f"{controller['type']} controller only adds corrections: the axis "
                                               "would run open loop")
    if controller["type"] == "task_frame_pd":
        expected = APPROXIMATIONS[controller["approximation"]]
        if estimator["type"] != expected:
            _fail(where, "/contour_estimator.type",
                  f"the task_frame_pd controller with approximation {controller['approximation']!r} acts on the "
                  f"errors of the {expected!r} estimator, got {estimator['type']!r}")


def parse_experiment(text: str, where: str = "<experiment>") -> Experiment:
    """Validate the YAML ``text`` of an experiment; ``where`` names it in errors."""
    return experiment_from_data(read_yaml(text, where), where, text)


def read_yaml(text: str, where: str = "<experiment>"):
    """The data of an experiment's YAML ``text`` (aliases refused, exponent floats read as numbers)."""
    try:
        data = yaml.load(text, Loader=_NoAliasLoader)
    except ConfigError as error:
        raise ConfigError(f"{where}: {error}") from None
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        line = f"line {mark.line + 1}: " if mark is not None else ""
        problem = getattr(error, "problem", None) or str(error).splitlines()[0]
        raise ConfigError(f"{where}: {line}not valid YAML ({problem})") from None
    return data


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
        path=where, text=text, sample_time=globals_["sample_time"], duration=globals_["duration"],
        axes=tuple(axes), curve=globals_["curve"], schedule=globals_["schedule"],
        initial_state=globals_["initial_state"], network=globals_["network"],
        stall_timeout=globals_["stall_timeout"], on_invalid_input=globals_["on_invalid_input"],
        timing=globals_["timing"], start_time=globals_["start_time"],
        ccc_takes_state=globals_["ccc_takes_state"],
        plants={a: parsed[f"/{a}/plant"] for a in axes}, servos={a: parsed[f"/{a}/servo"] for a in axes},
        estimator=parsed["/contour_estimator"], controller=parsed["/ccc"],
        info={"experiment": globals_["experiment"], "paper": globals_["paper"]})
    if not experiment.ccc_takes_state:
        check_ccc_takes_state(where, experiment, controller_uses_state(experiment))
    return experiment


def experiment_for_node(parameters: dict, node: str, role: str, where: str | None = None) -> Experiment:
    """Validate the parameters one node received (shared keys and its own section) like a file would be.

    ``parameters`` maps flat ROS parameter names to values; the other nodes' sections stay empty.
    """
    where = where or f"node {node}"
    nested = section_from_parameters({k: v for k, v in parameters.items() if k not in ROS_BUILTIN_PARAMETERS})
    globals_ = _validate_globals(where, {k: v for k, v in nested.items() if k in GLOBALS})
    section = _validate_role(where, node, role, {k: v for k, v in nested.items() if k not in GLOBALS}, globals_)
    axes = tuple(globals_["axes"])
    axis = node.strip("/").split("/")[0]
    return Experiment(
        path=where, text="", sample_time=globals_["sample_time"], duration=globals_["duration"], axes=axes,
        curve=globals_["curve"], schedule=globals_["schedule"], initial_state=globals_["initial_state"],
        network=globals_["network"], stall_timeout=globals_["stall_timeout"],
        on_invalid_input=globals_["on_invalid_input"], timing=globals_["timing"],
        start_time=globals_["start_time"], ccc_takes_state=globals_["ccc_takes_state"],
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


def load_experiment(path) -> Experiment:
    """Read and validate an experiment file."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as error:
        raise ConfigError(f"{path}: cannot read ({error.strerror})") from None
    if not raw.strip():
        raise ConfigError(f"{path}: the file is empty")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise ConfigError(f"{path}: not a text file (not UTF-8)") from None
    if "\x00" in text:
        raise ConfigError(f"{path}: not a text file (contains NUL bytes)")
    return parse_experiment(text, str(path))


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
    curve = _build_curve(section, where)
    curve.contour_error_window = section["contour_error_window"]
    return curve


def _build_curve(section: dict, where: str) -> curves.Curve:
    kind = section["type"]
    try:
        if kind == "parabola":
            return curves.Parabola(section["a"], section["h"])
        if kind == "circle":
            return curves.Circle(section["radius"], section["center"])
        if kind == "line":
            return curves.Line(section["start"], section["end"])
        if kind == "ellipse":
            return curves.Ellipse(section["a"], section["b"], section["center"])
        if kind == "figure_eight":
            return curves.FigureEight(section["a"], section["b"], section["center"])
        if kind == "spline":
            coordinates = [section["x"], section["y"]] + ([section["z"]] if section["z"] is not None else [])
            if len({len(c) for c in coordinates}) != 1:
                raise ValueError("x, y (and z) must list the same number of points")
            return curves.SplineCurve(np.column_stack(coordinates), section["closed"])
        if kind == "toolpath":
            return curves.ToolPath(section["start"], section["moves"])
        if kind == "butterfly":
            return curves.Butterfly(section["scale"], section["center"])
        if kind == "saddle":
            return curves.Saddle(section["a"], section["b"], section["h"], section["omega"])
        if kind == "helix":
            return curves.Helix(section["a"], section["b"], section["c"], section["omega"], section["length"])
    except ValueError as error:
        raise ConfigError(f"{where}: curve: {error}") from None
    raise ConfigError(f"{where}: curve.type: unknown name {kind!r}")


def build_curve(experiment: Experiment) -> curves.Curve:
    return build_curve_from(experiment.curve, experiment.path)


def build_schedule_from(section: dict, curve, where: str = "schedule"):
    if section["type"] == "feedrate":
        arguments = _kwargs(section)
        for key, default in (("theta_start", curve.domain[0]), ("theta_end", curve.domain[1])):
            if arguments[key] is None:
                arguments[key] = default
        try:
            return FeedrateSchedule(curve, **arguments)
        except ValueError as error:
            raise ConfigError(f"{where}: schedule: {error}") from None
    return UniformSchedule(**_kwargs(section))


def _schedule_duration(where: str, curve_section: dict, schedule_section: dict) -> float:
    if schedule_section["type"] == "uniform":
        return schedule_section["duration"]
    return build_schedule_from(schedule_section, build_curve_from(curve_section, where), where).duration


def build_schedule(experiment: Experiment, curve=None):
    return build_schedule_from(experiment.schedule, curve or build_curve(experiment), experiment.path)


def build_disturbance(section: dict):
    kind = section["type"]
    if kind == "none":
        return disturbances.NoDisturbance()
    if kind == "constant":
        return disturbances.ConstantDisturbance(section["value"])
    if kind == "random":
        return disturbances.RandomDisturbance(**_kwargs(section))
    return disturbances.SinusoidalDisturbance(**_kwargs(section))


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
    section = experiment.plants[axis]
    if section["model"] == "mass_damper":
        return plants.MassDamperAxis(section["mass"], section["damping"], section["gain"], experiment.sample_time,
                                     build_disturbance(section["disturbance"]), position, velocity,
                                     section["saturation"], section["coulomb_positive"],
                                     section["coulomb_negative"], section["disturbance_unit"],
                                     section["encoder_resolution"])
    return plants.FirstOrderVelocityAxis(section["gain"], section["time_constant"], experiment.sample_time,
                                         build_disturbance(section["disturbance"]), position, velocity,
                                         section["saturation"], section["encoder_resolution"])


def build_servo(experiment: Experiment, axis: str, position: float, velocity: float, acceleration: float):
    s, ts = experiment.servos[axis], experiment.sample_time
    if s["law"] == "eso_smc":
        return servo.ESOSlidingModeServo(s["mass"], s["damping"], s["gain"], s["c"], s["k"], s["alphas"], s["sigma"],
                                         ts, position, velocity, s["disturbance_compensation"], s["output_limit"])
    if s["law"] == "direct":
        return servo.DirectServo(s["output_limit"])
    if s["law"] == "cascade":
        return servo.CascadeServo(s["kp_position"], s["kp_velocity"], s["ki_velocity"], ts, s["coulomb_positive"],
                                  s["coulomb_negative"], s["output_limit"])
    if s["law"] == "pid":
        return servo.PIDServo(s["kp"], s["ki"], s["kd"], ts, s["output_limit"])
    if s["law"] == "pid_feedforward":
        return servo.PIDFeedforwardServo(s["kp"], s["ki"], s["kd"], s["gain"], s["time_constant"], ts,
                                         s["output_limit"])
    observer = servo.DisturbanceObserver(s["c"], s["d"], s["gain"], s["time_constant"], ts, velocity,
                                          acceleration) \
        if s["observer"] else None
    return servo.IntegralSlidingModeServo(s["a"], s["b"], s["mu"], s["kappa"], s["gain"], s["time_constant"],
                                          ts, observer, s["output_limit"])


def build_estimator(experiment: Experiment, curve):
    s = experiment.estimator
    if s["type"] == "tangent_line":
        return estimators.TangentLineEstimator(curve)
    if s["type"] == "natural_local":
        return estimators.NaturalLocalEstimator(curve)
    if s["type"] == "osculating_circle":
        return estimators.OsculatingCircleEstimator(curve)
    if s["type"] == "foot_point_search":
        return estimators.FootPointSearchEstimator(curve, s["max_iterations"], s["tolerance"])
    theta0 = s["theta0"] if s["theta0"] is not None else build_schedule(experiment, curve).theta_start
    inner = s["inner_step"] or experiment.sample_time
    check = estimators.BranchCheck(curve, s["branch_check_samples"], s["branch_check_tolerance"]) \
        if s["branch_check_samples"] else None
    return estimators.NewtonEstimator(curve, s["k_prime"], s["c_prime"], theta0, s["iterations"], inner, check)


def build_controller(experiment: Experiment, curve):
    s, ts = experiment.controller, experiment.sample_time
    if s["type"] == "none":
        return contouring.NoCoupling(len(experiment.axes))
    if s["type"] == "task_frame_pd":
        approximation = {"first_order": estimators.first_order_terms,
                         "natural_local": estimators.natural_local_terms}[s["approximation"]]
        return contouring.TaskFramePD(curve, approximation, s["mass"], s["damping"], s["gain"],
                                      [s["f_t"], s["f_n"]] + ([s["f_b"]] if s["f_b"] is not None else []), s["zeta"], s["coulomb_positive"],
                                      s["coulomb_negative"])
    if s["type"] == "tvt":
        return contouring.TangentialVelocityCCC(curve, build_schedule(experiment, curve), s["kc"], s["min_feedrate"])
    if s["type"] == "adaptive_tnb":
        return contouring.AdaptiveTNBCCC(curve, s["coupling"], s["alpha"], s["gamma_mass"], s["gamma_damping"],
                                         s["mass0"], s["damping0"], ts)
    if s["type"] == "variable_gain":
        return contouring.VariableGainCCC(curve, s["kp"], s["ki"], s["kd"], ts, s["output_limit"])
    return contouring.UnitVectorCCC(len(experiment.axes), s["kp"], s["ki"], s["kd"], ts, s["output_limit"])


def build_loop(experiment: Experiment) -> ControlLoop:
    """Every core object of the experiment, in their initial state."""
    curve = build_curve(experiment)
    schedule = build_schedule(experiment, curve)
    positions, velocities, accelerations = initial_state(experiment, curve, schedule)
    axes = experiment.axes
    return ControlLoop(
        curve=curve, schedule=schedule,
        plants=[build_plant(experiment, a, positions[i], velocities[i]) for i, a in enumerate(axes)],
        servos=[build_servo(experiment, a, positions[i], velocities[i], accelerations[i])
                for i, a in enumerate(axes)],
        estimator=build_estimator(experiment, curve), controller=build_controller(experiment, curve),
        sample_time=experiment.sample_time, n_steps=experiment.n_steps)
