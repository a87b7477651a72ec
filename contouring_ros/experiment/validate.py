"""Validating an experiment: the shared keys, each node's section against its role's catalogue entry, the
combination of estimator, controller and servos, and the parameters one node received. Every problem is a
:class:`~contouring_ros.errors.ConfigError` of one line naming the file (or node) and the key.

An experiment is one ROS 2 parameter file. Keys shared by every node live under ``/**: ros__parameters``;
each node has its own section, named by its fully qualified node name::

    /**:            ros__parameters: {sample_time, duration, axes, curve, schedule, initial_state, ...}
    /<axis>/plant:  ros__parameters: {model, <model parameters>, disturbance}
    /<axis>/servo:  ros__parameters: {law, <law parameters>}
    /contour_estimator: ros__parameters: {type, <estimator parameters>}
    /ccc:           ros__parameters: {type, <controller parameters>}
"""
from __future__ import annotations

import re
from dataclasses import fields

import numpy as np

from ..wire import graph
from ..errors import ConfigError
from ..wire.graph import graph_namespace
from ..wire import catalogue as nodes
from ..core.feed_control import parse_feed_events
from .build import build_curve_from, in_position_windows, planned_tool_path, schedule_duration
from .catalogue import CONTROLLERS, GLOBALS, OPTIONAL_NODES, ROLE_TYPES, SERVOS
from .catalogue.curves import TOOL_PATH_TYPES
from .model import Experiment
from .ros_yaml import read_yaml
from .schema import GLOBAL_SECTION, MAX_DURATION, MAX_STEPS, ROS_PARAMETERS, _fail, _mapping, _printable, _show, _typed

__all__ = ["parse_experiment", "experiment_from_data", "experiment_for_node", "node_sections", "split_groups",
           "check_ccc_takes_state", "controller_uses_state", "section_from_parameters", "ROS_BUILTIN_PARAMETERS",
           "RESERVED_AXIS_NAMES", "is_axis_name", "validate_section"]

ROS_BUILTIN_PARAMETERS = {"use_sim_time", "start_type_description_service"}  # every rclpy node declares these
_AXIS_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,31}$")
_EXPERIMENT_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}$")
RESERVED_AXIS_NAMES = {"theta", "contour_error", "foot_point_parameter"}   # other joint names of the messages


def is_axis_name(name) -> bool:
    """An axis name: 1 to 32 ASCII letters, digits and single _, starting with a letter (it becomes a ROS
    namespace), and none of RESERVED_AXIS_NAMES (the messages' other joint names)."""
    return isinstance(name, str) and bool(_AXIS_NAME.match(name)) and "__" not in name \
        and name not in RESERVED_AXIS_NAMES


def _ros_parameters(where, node: str, body) -> dict:
    if not isinstance(body, dict) or set(body) != {ROS_PARAMETERS} or not isinstance(body[ROS_PARAMETERS], dict):
        _fail(where, node, f"expected a mapping with the single key '{ROS_PARAMETERS}'")
    return body[ROS_PARAMETERS]


def node_sections(axes) -> dict:
    """Node name -> role for the graph of ``axes`` (the fully qualified names used in experiment files)."""
    return nodes.experiment_sections(axes)


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
        if not is_axis_name(axis):
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
    for key in ("in_position", "following_error_limit"):
        if len(out[key]) not in (1, len(axes)):
            _fail(where, key, f"expected 1 value or one per axis ({len(axes)}), got {len(out[key])}")
    try:
        parse_feed_events(out["feed_events"], out["sample_time"])
    except ValueError as error:
        _fail(where, "feed_events", str(error))
    if out["feed_events"] and not planned_tool_path(out):
        _fail(where, "feed_events", "a feed hold stops the run on the path, which needs a tool path planned by the "
                                    "feed plan (a gcode curve, or a toolpath with a feedrate schedule with jerk)")
    if (out["contour_error_limit"] or any(out["following_error_limit"])) and not planned_tool_path(out):
        key = "contour_error_limit" if out["contour_error_limit"] else "following_error_limit"
        _fail(where, key, "monitoring stops the run on the path, which needs a tool path planned by the feed plan "
                          "(a gcode curve, or a toolpath with a feedrate schedule with jerk)")
    if out["duration"] == 0.0:
        try:
            duration, stops = schedule_duration(out["curve"], out["schedule"], curve, where)
            # with in-position checks every exact stop may wait up to its timeout
            waits = stops * out["schedule"]["in_position_timeout"] if in_position_windows(out) is not None else 0.0
            out["duration"] = duration + waits + out["settle_time"]
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
    return validate_section(where, node, registry, given, tuple(globals_["axes"]))


def validate_section(where, node: str, registry, given: dict, axes: tuple) -> dict:
    """One section of ``registry``'s role (``node`` names it in errors): its type, its keys against that
    type's Params (defaults filled in) and the type's own constraint, for ``axes``."""
    section = _typed(where, node, registry.type_key, registry, given)
    _check_entry(where, node, registry.entry(section[registry.type_key]), section, tuple(axes))
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
    out["following_error_limit"] = tuple(out["following_error_limit"])
    out["feed_events"] = tuple(out["feed_events"])
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
        namespace = graph_namespace(node, role in nodes.PER_AXIS)
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
    """Whether the experiment's contour controller uses the reference and the axis states (its catalogue
    entry's ``needs_state``), i.e. whether the CCC node must take them (the shared key ``ccc_takes_state``)."""
    return CONTROLLERS.entry(experiment.controller["type"]).needs_state


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
