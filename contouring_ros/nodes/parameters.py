"""ROS parameter descriptors of the graph's nodes, built from the specs the experiment validator checks.

Every parameter a node holds (the shared keys of ``/**`` and its own section, given in the file or left to
their defaults) is declared with a ``ParameterDescriptor``: its description with the unit, its type, the
range its :class:`~contouring_ros.experiment.schema.Param` states (the catalogue's, in
contouring_ros/experiment/catalogue/), the names it may take, and ``read_only``: a node reads
its parameters once, before the first step, so ``ros2 param set`` is refused rather than silently ignored.
``ros2 param describe /x/servo kp`` then says what the key is; a plain rclpy client reads the same through
the standard parameter services (tests/experiment/test_parameters.py).

No rclpy import at module level: :func:`node_parameters` is plain data; :func:`descriptor` builds the message.
"""
from __future__ import annotations

from ..experiment.catalogue import GLOBALS, OPTIONAL_NODES, ROLE_TYPES
from ..experiment.schema import DEFAULT_BOUNDS, NUMERIC_KINDS, Param
from ..experiment.validate import ROS_BUILTIN_PARAMETERS, experiment_for_node

__all__ = ["NodeParameter", "node_parameters", "description", "describe", "descriptor"]


class NodeParameter:
    """One parameter of a node: flat ROS name, value, the Param that checks it, what it means."""

    __slots__ = ("name", "value", "spec", "description", "given")

    def __init__(self, name: str, value, spec: Param | None, description: str, given: bool):
        self.name, self.value, self.spec, self.description, self.given = name, value, spec, description, given


def description(spec: Param | None, key: str) -> str:
    """What a key means, with its unit: its Param's ``help`` (the catalogue's, or a plugin's own), else its
    name; the names it may take."""
    text = (spec.help if spec is not None else "") or key
    if spec is not None and isinstance(spec.choices, tuple):
        text += f" (one of: {', '.join(spec.choices)})"
    return text


def _type_key(registry) -> Param:
    return Param("str", help=registry.description)


def _walk(prefix: str, specs: dict, section: dict, given: dict, out: dict):
    """Flatten one validated ``section`` (defaults filled) into ``out``: name -> NodeParameter."""
    for key, value in section.items():
        name = f"{prefix}{key}"
        spec = specs.get(key)
        if spec is not None and spec.kind == "dict" and spec.choices is not None and isinstance(value, dict):
            registry = spec.choices
            entry_specs = registry.entry(value[registry.type_key]).params
            _walk(f"{name}.", {registry.type_key: _type_key(registry), **entry_specs}, value, given, out)
        elif isinstance(value, dict):       # free-form (experiment, paper): the keys the file gave
            _walk(f"{name}.", {}, value, given, out)
        else:
            out[name] = NodeParameter(name, value, spec, description(spec, key), name in given)


def node_parameters(parameters: dict, node: str, role: str, experiment=None) -> dict:
    """Every parameter of ``node`` (its fully qualified name; ``role`` as in experiment.catalogue.ROLE_TYPES or
    OPTIONAL_NODES) from the flat ``parameters`` it received: the given ones and the defaults the
    validator filled in, each with its Param and description. Values that ROS cannot hold as a typed
    parameter (None: "the curve's own"; an empty list) are left out. ``experiment``: the node's validated
    experiment where the caller has it (experiment_for_node of the same parameters)."""
    experiment = experiment or experiment_for_node(parameters, node, role)
    given = {name for name in parameters if name not in ROS_BUILTIN_PARAMETERS}
    shared = {key: _shared_value(experiment, key, parameters) for key in GLOBALS}
    out: dict = {}
    _walk("", GLOBALS, shared, given, out)
    section = experiment.info["node"]
    if role in OPTIONAL_NODES:
        _walk("", OPTIONAL_NODES[role], section, given, out)
    else:
        type_key, registry = ROLE_TYPES[role]
        specs = {type_key: _type_key(registry), **registry.entry(section[type_key]).params}
        _walk("", specs, section, given, out)
    for name in given:        # what was given keeps the value (and type) the node received
        if name in out:
            out[name].value = parameters[name]
    return {name: p for name, p in out.items()
            if p.value is not None and not (isinstance(p.value, (list, tuple)) and len(p.value) == 0)}


def _shared_value(experiment, key: str, parameters: dict):
    """A shared key's validated value (the given one where the Experiment keeps none, e.g. settle_time)."""
    if key in ("experiment", "paper"):
        return experiment.info[key]
    if not hasattr(experiment, key):
        return parameters.get(key, GLOBALS[key].default)
    value = getattr(experiment, key)
    return list(value) if isinstance(value, tuple) else value


def describe(parameter: NodeParameter) -> str:
    """The descriptor's description: meaning and unit, kind, range, and that it is read once."""
    spec = parameter.spec
    text = parameter.description
    if spec is not None and spec.kind in NUMERIC_KINDS:
        low, high = spec.bounds or DEFAULT_BOUNDS[spec.kind]
        text += f"; from {low:g} to {high:g}"
    origin = "given in the experiment file" if parameter.given else "default"
    return f"{text}; {origin}; read once at start"


def descriptor(parameter: NodeParameter):
    """The rcl_interfaces ParameterDescriptor of ``parameter`` (read-only, with its range where it is a
    scalar number)."""
    from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
    from rclpy.parameter import Parameter
    spec = parameter.spec
    out = ParameterDescriptor(name=parameter.name, description=describe(parameter), read_only=True,
                              type=Parameter.Type.from_parameter_value(parameter.value).value)
    if spec is not None and spec.kind in ("float", "int") and not isinstance(parameter.value, bool):
        low, high = spec.bounds or DEFAULT_BOUNDS[spec.kind]
        if spec.kind == "float" and isinstance(parameter.value, float):
            out.floating_point_range = [FloatingPointRange(from_value=float(low), to_value=float(high), step=0.0)]
        elif spec.kind == "int" and isinstance(parameter.value, int):
            out.integer_range = [IntegerRange(from_value=int(low), to_value=int(high), step=1)]
    if spec is not None and isinstance(spec.choices, tuple):
        out.additional_constraints = f"one of: {', '.join(spec.choices)}"
    return out
