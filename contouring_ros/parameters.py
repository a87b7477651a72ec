"""ROS parameter descriptors of the graph's nodes, built from the specs the experiment validator checks.

Every parameter a node holds (the shared keys of ``/**`` and its own section, given in the file or left to
their defaults) is declared with a ``ParameterDescriptor``: its description with the unit, its type, the
range :data:`contouring_ros.config.BOUNDS` gives it, the names it may take, and ``read_only``: a node reads
its parameters once, before the first step, so ``ros2 param set`` is refused rather than silently ignored.
``ros2 param describe /x/servo kp`` then says what the key is; a plain rclpy client reads the same through
the standard parameter services (tests/test_parameters.py).

No rclpy import at module level: :func:`node_parameters` is plain data; :func:`descriptor` builds the message.
"""
from __future__ import annotations

from . import config
from .config import DEFAULT_BOUNDS, GLOBALS, NUMERIC_KINDS, OPTIONAL_NODES, ROLE_TYPES, Param
from .nodes import catalogue

__all__ = ["DESCRIPTIONS", "NodeParameter", "node_parameters", "describe", "descriptor"]

_M, _S = "[m]", "[s]"
#: what each key means, with its unit, by the table its Params live in (as config.BOUNDS); a type's own
#: entry ("type.key") before the key's; keys not named here are described by their role, type and kind
DESCRIPTIONS = {
    "GLOBALS": {
        "sample_time": f"control period Ts {_S}", "duration": f"simulated time of the run, 0: the schedule's own {_S}",
        "settle_time": f"simulated time run past the schedule's end {_S}", "axes": "axis names, in order",
        "initial_state": "where the axes start", "network": "discover nodes beyond localhost",
        "stall_timeout": f"wall time without a complete step before a node gives up {_S}",
        "graph_timeout": f"wall time a node waits at start for the rest of the graph {_S}",
        "divergence_factor": "the run stops once an axis is this many path sizes from its reference (0: never)",
        "on_invalid_input": "what a node does with a non-finite or malformed input",
        "timing": "lockstep (as fast as the graph goes) or realtime (one step a period of wall time)",
        "start_time": "realtime: Unix time of tick 0 [s since 1970]",
        "ccc_takes_state": "the CCC node subscribes to the reference and the axis states",
        "namespaced_clock": "under a namespace, /clock and /diagnostics take it too (else they stay global)",
        "layout": "where contouring-ros run puts the nodes: a process each, all in one, or the processes of groups",
        "groups": "grouped layout: the nodes of each process, e.g. 'x/plant,x/servo; y/plant,y/servo'",
        "in_position": f"drives' in-position window, one or one per axis: exact stops wait for it, 0: no wait {_M}"},
    "CURVES": {
        "type": "curve type", "a": f"size a {_M}", "b": f"size b {_M}", "radius": f"radius {_M}", "scale": f"scale {_M}",
        "h": "shape parameter h", "c": f"pitch term c {_M}", "omega": "angular rate [rad per unit of parameter]",
        "length": "parameter length", "center": f"centre {_M}", "start": f"start point {_M}", "end": f"end point {_M}",
        "x": f"x coordinates of the points {_M}", "y": f"y coordinates of the points {_M}",
        "z": f"z coordinates of the points {_M}", "closed": "the spline closes on itself",
        "moves": "tool path moves (G1/G2/G3 words)", "file": "part program (RS274/NGC subset), absolute path",
        "gcode.start": f"where the program starts {_M}",
        "blend_tolerance": f"corner blending within this distance of the corner (as G64 P), 0: exact stop (G61) {_M}",
        "strict": "refuse the part program's setup words (G40, G54, M3, T ...) instead of reading and reporting them",
        "contour_error_window": "parameter half-width the exact contour error searches around the reference (0: whole curve)"},
    "SCHEDULES": {
        "type": "schedule type", "theta_start": "curve parameter at t = 0", "theta_end": "curve parameter at the end",
        "duration": f"time from theta_start to theta_end {_S}", "feedrate": "commanded feedrate [m/s]",
        "acceleration": "tangential acceleration bound [m/s^2]",
        "normal_acceleration": "centripetal acceleration bound, 0: none [m/s^2]",
        "samples": "points of the feedrate profile table", "jerk": "path jerk bound, 0: no jerk limit [m/s^3]",
        "rapid_feedrate": "G0 feedrate, 0: the commanded feedrate [m/s]", "axis_feedrate": "per-axis speed bounds [m/s]",
        "axis_acceleration": "per-axis acceleration bounds [m/s^2]", "axis_jerk": "per-axis jerk bounds [m/s^3]",
        "contour_tolerance": f"lower the feed where the predicted contour error exceeds this, 0: off {_M}",
        "tracking_lag": f"each axis' tracking lag for the contour-error prediction {_S}",
        "exact_stop_dwell": f"dwell at each exact-stop corner {_S}",
        "feed_override": "feed override [percent of every programmed feed, rapids included]",
        "in_position_timeout": f"the longest the reference waits at one exact stop for the axes {_S}"},
    "DISTURBANCES": {
        "type": "disturbance type", "value": "constant disturbance [command units or m/s^2]",
        "amplitude": "amplitude [command units or m/s^2]", "offset": "offset [command units or m/s^2]",
        "frequency": "frequency [Hz]", "phase": "phase [rad]", "std": "standard deviation [command units or m/s^2]",
        "seed": "random seed"},
    "PLANTS": {
        "model": "plant model", "gain": "actuator gain [m/s per command unit (velocity axis), N per command unit (mass)]",
        "time_constant": f"velocity loop time constant {_S}", "mass": "moving mass [kg]", "damping": "viscous damping [N s/m]",
        "coulomb_positive": "Coulomb friction moving forward [N]", "coulomb_negative": "Coulomb friction moving back [N]",
        "disturbance_unit": "what the disturbance is given in", "saturation": "command limit, 0: none [command units]",
        "encoder_resolution": f"position quantisation, 0: none {_M}", "disturbance": "load disturbance",
        "measurement_noise": f"standard deviation of the white Gaussian noise on the position reading, 0: none {_M}",
        "noise_seed": "seed of the measurement noise (same seed, same noise)",
        "command_delay": "computation delay: a command acts this many periods after it is computed [samples]",
        "velocity_measurement": "the velocity reading: the drive's own (model) or the differentiated encoder"},
    "SERVOS": {
        "law": "servo law", "kp": "proportional gain [command units/m]", "ki": "integral gain [command units/(m s)]",
        "kd": "derivative gain [command units s/m]", "kp_position": "position loop gain [1/s]",
        "kp_velocity": "velocity loop gain [command units s/m]", "ki_velocity": "velocity loop integral gain [command units/m]",
        "output_limit": "command limit, 0: none (anti-windup when hit) [command units]",
        "gain": "model actuator gain [m/s per command unit]", "time_constant": f"model time constant {_S}",
        "a": "sliding surface gain a [1/s]", "b": "sliding surface gain b [1/s^2]", "mu": "boundary layer width",
        "kappa": "switching gain", "c": "observer gain c [1/s]", "d": "observer gain d [1/s^2]",
        "observer": "use the disturbance observer",
        "observer_plan_correction": "add to eq. 25 its filter mismatch computed on the reference (not in the paper): "
                                    "the plan's jerk no longer read as load", "k": "sliding gain k", "sigma": "boundary layer sigma",
        "alphas": "extended state observer gains", "mass": "model mass [kg]", "damping": "model damping [N s/m]",
        "coulomb_positive": "model Coulomb friction forward [N]", "coulomb_negative": "model Coulomb friction back [N]",
        "disturbance_compensation": "subtract the observer's disturbance estimate"},
    "ESTIMATORS": {
        "type": "contour error estimator", "k_prime": "Newton step gain k' [1/s]", "c_prime": "Newton step gain c' [1/s]",
        "theta0": "initial foot-point parameter (default: the schedule's start)",
        "inner_step": f"inner iteration step, 0: the sample time {_S}",
        "tolerance": f"stop iterating when the residual and the step are below this {_M}",
        "max_iterations": "iteration cap per control step",
        "branch_check_samples": "samples of the global branch check, 0: none",
        "branch_check_tolerance": f"how much closer another branch must be to jump there {_M}"},
    "CONTROLLERS": {
        "type": "cross-coupled controller", "kp": "proportional gain [command units/m]",
        "ki": "integral gain [command units/(m s)]", "kd": "derivative gain [command units s/m]",
        "output_limit": "correction limit, 0: none [command units]", "mass": "axis masses [kg]",
        "damping": "axis damping [N s/m]", "gain": "actuator gains [N per command unit]",
        "coulomb_positive": "Coulomb friction forward [N]", "coulomb_negative": "Coulomb friction back [N]",
        "f_t": "tangential bandwidth [Hz]", "f_n": "normal bandwidth [Hz]", "f_b": "binormal bandwidth [Hz]",
        "zeta": "damping ratio", "approximation": "local contour approximation", "kc": "tangential velocity gain [1/s]",
        "min_feedrate": "feedrate floor [m/s]", "coupling": "coupling gains", "alpha": "tracking gain alpha [1/s]",
        "gamma_mass": "mass adaptation gains", "gamma_damping": "damping adaptation gains",
        "mass0": "initial mass estimates [kg]", "damping0": "initial damping estimates [N s/m]"},
    "OPTIONAL": {"bag": "the MCAP file to write", "experiment_file": "experiment file stored in the bag"},
}
_TABLE_OF_ROLE = {node.name: node.parameters for node in catalogue.NODES}    # node -> its keys' table
_TABLE_OF_REGISTRY = {"curve": "CURVES", "schedule": "SCHEDULES", "disturbance": "DISTURBANCES"}


class NodeParameter:
    """One parameter of a node: flat ROS name, value, the Param that checks it, what it means."""

    __slots__ = ("name", "value", "spec", "description", "given")

    def __init__(self, name: str, value, spec: Param | None, description: str, given: bool):
        self.name, self.value, self.spec, self.description, self.given = name, value, spec, description, given


def _describe(table: str, type_name: str, key: str, spec: Param | None) -> str:
    known = DESCRIPTIONS.get(table, {})
    text = known.get(f"{type_name}.{key}") or known.get(key) or (spec.help if spec is not None else "") or key
    if spec is not None and isinstance(spec.choices, tuple):
        text += f" (one of: {', '.join(spec.choices)})"
    return text


def _walk(prefix: str, table: str, type_name: str, specs: dict, section: dict, given: dict, out: dict):
    """Flatten one validated ``section`` (defaults filled) into ``out``: name -> NodeParameter."""
    for key, value in section.items():
        name = f"{prefix}{key}"
        spec = specs.get(key)
        if spec is not None and spec.kind == "dict" and spec.choices is not None and isinstance(value, dict):
            registry = spec.choices
            type_key = "type"
            inner_table = _TABLE_OF_REGISTRY.get(registry.role, table)
            entry_specs = registry.entry(value[type_key]).params
            _walk(f"{name}.", inner_table, value[type_key], {type_key: Param("str"), **entry_specs}, value, given, out)
        elif isinstance(value, dict):       # free-form (experiment, paper): the keys the file gave
            _walk(f"{name}.", table, type_name, {}, value, given, out)
        else:
            out[name] = NodeParameter(name, value, spec, _describe(table, type_name, key, spec), name in given)


def node_parameters(parameters: dict, node: str, role: str, experiment=None) -> dict:
    """Every parameter of ``node`` (its fully qualified name; ``role`` as in config.ROLE_TYPES or
    OPTIONAL_NODES) from the flat ``parameters`` it received: the given ones and the defaults the
    validator filled in, each with its Param and description. Values that ROS cannot hold as a typed
    parameter (None: "the curve's own"; an empty list) are left out. ``experiment``: the node's validated
    experiment where the caller has it (config.experiment_for_node of the same parameters)."""
    experiment = experiment or config.experiment_for_node(parameters, node, role)
    given = {name for name in parameters if name not in config.ROS_BUILTIN_PARAMETERS}
    shared = {key: _shared_value(experiment, key, parameters) for key in GLOBALS}
    out: dict = {}
    _walk("", "GLOBALS", "", GLOBALS, shared, given, out)
    section = experiment.info["node"]
    if role in OPTIONAL_NODES:
        _walk("", _TABLE_OF_ROLE[role], role, OPTIONAL_NODES[role], section, given, out)
    else:
        type_key, registry = ROLE_TYPES[role]
        specs = {type_key: Param("str"), **registry.entry(section[type_key]).params}
        _walk("", _TABLE_OF_ROLE[role], section[type_key], specs, section, given, out)
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
