"""The node graph: nodes, topics, message layouts and QoS, in one place (which nodes there are and the topics
each takes and publishes come from the node catalogue, contouring_ros/wire/catalogue.py).

No rclpy import here: the bag reader and the analysis use the same layouts on decoded messages.

Topic table (N axes named in the experiment's ``axes``; every message stamped t_k = k Ts). The names are
the graph's own, relative to the namespace it runs under (``contouring-ros run --namespace m1`` puts /m1
before every node and topic: /m1/x/plant publishes /m1/x/state); :func:`resolve` gives the name on the wire.

| topic               | type                             | publisher          | content (SI units)                                  |
|---------------------|----------------------------------|--------------------|-----------------------------------------------------|
| /clock              | rosgraph_msgs/msg/Clock          | interpolator       | simulated time t_k, once step k is under way        |
| /reference          | trajectory_msgs/msg/JointTrajectory | interpolator    | joint_names = axes + [theta]; one point: positions [m], velocities [m/s], accelerations [m/s^2] of each axis, then theta and its derivatives; then the preview points a ZPETC servo reads (positions only) |
| /<axis>/state       | sensor_msgs/msg/JointState       | /<axis>/plant      | name [axis]; position [m], velocity [m/s] at step k |
| /contour_error      | sensor_msgs/msg/JointState       | /contour_estimator | name = axes + [contour_error, foot_point_parameter]; position = error vector [m], signed error [m], theta_hat |
| /ccc/correction     | sensor_msgs/msg/JointState       | /ccc               | name = axes; effort = correction per axis [command units] |
| /<axis>/command     | sensor_msgs/msg/JointState       | /<axis>/servo      | name [axis]; effort = actuator command [command units] |
| /diagnostics        | diagnostic_msgs/msg/DiagnosticArray | every node      | rejected inputs; end-of-run counts (not every step) |
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from ..core.estimators import ContourEstimate
from ..core.interpolation import Reference
from ..errors import ConfigError
from . import catalogue
from .catalogue import CLOCK, COMMAND, CONTOUR_ERROR, CORRECTION, DIAGNOSTICS, REFERENCE, STATE

__all__ = ["Topic", "topics", "node_names", "NodeSpec", "node_specs", "CONTOUR_ERROR_NAME", "FOOT_POINT_NAME", "THETA_NAME",
           "LOOKAHEAD", "step_to_stamp", "reference_from_msg",
           "estimate_from_msg", "estimate_names", "estimate_values", "state_topic", "command_topic",
           "message_problem", "recorded_topics", "normalize_namespace", "resolve", "GLOBAL_TOPICS", "graph_namespace",
           "namespace_of_topics", "PROGRESS_ENV", "write_progress", "read_progress"]

#: the environment variable naming the file where a run's recorder keeps its progress (the steps recorded in
#: full) for the runner's progress bar; set by the runner, absent for nodes started by hand
PROGRESS_ENV = "CONTOURING_ROS_PROGRESS_FILE"
PROGRESS_WIDTH = 20      # the file holds one right-aligned number of this width and a newline, rewritten in place


def write_progress(fd: int, steps: int) -> None:
    """Record ``steps`` (recorded in full) in the progress file open as ``fd``: one write at offset 0."""
    import os
    os.pwrite(fd, f"{steps:>{PROGRESS_WIDTH}}\n".encode(), 0)


def read_progress(path) -> int | None:
    """The steps the progress file at ``path`` says are recorded, or None before the recorder wrote any."""
    try:
        with open(path, "rb") as stream:
            text = stream.read(PROGRESS_WIDTH + 1)
    except OSError:
        return None
    try:
        return int(text) if len(text) == PROGRESS_WIDTH + 1 else None
    except ValueError:
        return None

THETA_NAME = "theta"
CONTOUR_ERROR_NAME = "contour_error"
FOOT_POINT_NAME = "foot_point_parameter"
LOOKAHEAD = 2   # the interpolator publishes the reference this many steps ahead of the estimator


@dataclass(frozen=True)
class Topic:
    """One topic of the graph: its name, ROS type, the node that publishes it and the nodes that take it."""

    name: str
    type: str
    publisher: str
    subscribers: tuple
    layout: tuple = ()    # (field, length) pairs every message must have, values finite
    every_step: bool = True   # one message per step (else event-driven, like /diagnostics)
    names: tuple | None = None   # the joint names every message must carry (None: not checked)


_NAMESPACE_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def normalize_namespace(namespace: str | None) -> str:
    """The absolute form of a graph namespace ("m1", "/m1/", "/lab/m1" -> "/m1", "/m1", "/lab/m1"; None or
    "" or "/" -> "/"); ValueError, in one line, for a name ROS refuses (each part a letter or '_', then
    letters, digits, '_')."""
    text = (namespace or "").strip()
    tokens = [t for t in text.strip("/").split("/")] if text.strip("/") else []
    for token in tokens:
        if not _NAMESPACE_TOKEN.fullmatch(token):
            raise ValueError(f"namespace {namespace!r}: {token!r} is not a ROS name part (a letter or '_', "
                             "then letters, digits and '_', parts separated by one '/')")
        if "__" in token:
            raise ValueError(f"namespace {namespace!r}: {token!r} holds '__', which ROS keeps for its own names")
    out = "/" + "/".join(tokens)
    if len(out) > MAX_NAMESPACE:
        raise ValueError(f"namespace of {len(out)} characters: at most {MAX_NAMESPACE} (ROS limits a topic name's "
                         "length, and the graph's topics add up to 41 characters to it)")
    return out


MAX_NAMESPACE = 160   # characters of a graph namespace: /<ns>/<axis of 32>/command stays within ROS's name limit


GLOBAL_TOPICS = (CLOCK, DIAGNOSTICS)   # global under any namespace, as ROS tools expect (use_sim_time nodes
                                       # subscribe to /clock, diagnostic aggregators to /diagnostics)


def resolve(namespace: str, name: str, namespaced_clock: bool = False) -> str:
    """The name on the wire of the graph's topic or node ``name`` (absolute in the graph, e.g. /x/state)
    under the graph ``namespace``; /clock and /diagnostics stay global unless ``namespaced_clock`` (the
    experiment key of that name: several graphs sharing one domain, each with its own clock)."""
    if namespace in ("", "/") or (name in GLOBAL_TOPICS and not namespaced_clock):
        return name
    return namespace.rstrip("/") + name


def graph_namespace(node_full_name: str, per_axis: bool) -> str:
    """The namespace of the graph a node belongs to, from its fully qualified name: its own namespace,
    less the axis part for a per-axis node (/m1/x/plant -> /m1; /m1/ccc -> /m1; /x/plant -> /)."""
    parts = node_full_name.strip("/").split("/")
    return "/" + "/".join(parts[:-2] if per_axis else parts[:-1])


def namespace_of_topics(names) -> str:
    """The namespace a set of recorded topic names was recorded under: the part before the one name that
    ends in /reference (the graph's own names end the same way under any namespace). ValueError when
    several graphs' /reference topics are there."""
    prefixes = sorted({name[:-len(REFERENCE)] or "/" for name in names if name.endswith(REFERENCE)})
    if len(prefixes) > 1:
        raise ValueError(f"topics of several graphs (namespaces {', '.join(prefixes)}); record one graph a bag")
    return prefixes[0] if prefixes else "/"


def state_topic(axis: str) -> str:
    return catalogue.on_axis(STATE, axis)


def command_topic(axis: str) -> str:
    return catalogue.on_axis(COMMAND, axis)


def node_names(axes) -> list:
    """Fully qualified names of every node of the graph, in the order of a step (wire.catalogue), recorder
    last."""
    return [name for _, _, name in catalogue.instances(axes)]


@dataclass(frozen=True)
class NodeSpec:
    """How one node of the graph is started: what the runner and launch/contouring.launch.py share.

    ``name`` is the node concern's name in wire.catalogue, ``executable`` its console script
    (``ros2 run contouring_ros <executable>``); ``overrides`` are parameters set on top of the experiment file.
    """

    name: str
    namespace: str
    executable: str
    overrides: tuple = ()     # (name, value) pairs

    @property
    def full_name(self) -> str:
        return f"{self.namespace.rstrip('/')}/{self.name}"

    @property
    def module(self) -> str:
        """The node's module (what the runner starts with ``python -m``)."""
        return catalogue.NODE[self.name].module


def node_specs(axes, overrides: dict | None = None, bag: str | None = None,
               experiment_file: str | None = None, namespace: str = "/") -> list:
    """Every node of the graph for ``axes``, recorder first: its name, namespace (under the graph's
    ``namespace``), executable and the parameters set on top of the experiment file (``overrides`` for
    every node; the recorder also gets ``bag`` and ``experiment_file`` where given)."""
    shared = tuple((overrides or {}).items())
    out = []
    for full_name in ["/recorder"] + [n for n in node_names(axes) if n != "/recorder"]:
        parts = resolve(namespace, full_name).strip("/").split("/")
        name, node_namespace = parts[-1], "/" + "/".join(parts[:-1])
        extra = ()
        if name == "recorder":
            extra = tuple((key, value) for key, value in (("bag", bag), ("experiment_file", experiment_file))
                          if value is not None)
        node = catalogue.NODE[name]
        out.append(NodeSpec(name, node_namespace, node.console_script, extra + shared))
    return out


def topics(axes, ccc_takes_state: bool = True, interpolator_takes_state: bool = False) -> list:
    """Every topic of the graph for ``axes``: the outputs of the nodes of wire.catalogue, in graph order,
    each with its publisher and subscribers (those whose step reads it, those it only paces, then the
    recorder, which takes them all). The CCC takes /reference and the states only with ``ccc_takes_state``
    (the shared key of that name: its controller uses them); the interpolator takes the states only with
    ``interpolator_takes_state`` (exact stops wait for the axes, or following-error monitoring:
    ``experiment.build.interpolator_takes_state``)."""
    flags = {"ccc_takes_state": ccc_takes_state, "interpolator_takes_state": interpolator_takes_state}
    nodes = catalogue.instances(axes)
    out = []
    for node, axis, publisher in nodes:
        for template in node.outputs:
            for name in catalogue.expand(template, axes, axis):
                layout, names = _message(template, axes, axis)
                out.append(Topic(name, catalogue.TOPIC_TYPES[template], publisher,
                                 _subscribers(name, nodes, axes, flags), layout, names=names))
    return out


def _subscribers(name: str, nodes, axes, flags: dict) -> tuple:
    """The nodes that take the topic ``name``, ordered by how they use it (catalogue.USES), then graph order."""
    takers = [(catalogue.USES.index(i.use), full_name) for node, axis, full_name in nodes for i in node.inputs
              if (i.when is None or flags[i.when])
              and (i.topic == catalogue.EVERY_TOPIC or name in catalogue.expand(i.topic, axes, axis))]
    return tuple(full_name for _, full_name in sorted(takers, key=lambda taker: taker[0]))


def _message(topic: str, axes, axis) -> tuple:
    """(layout, joint names) every message of ``topic`` (as the catalogue names it; of ``axis`` where per
    axis) must have."""
    n = len(axes)
    if topic == REFERENCE:
        return (("positions", n + 1), ("velocities", n + 1), ("accelerations", n + 1)), tuple(axes) + (THETA_NAME,)
    if topic == STATE:
        return (("position", 1), ("velocity", 1)), (axis,)
    if topic == CONTOUR_ERROR:
        return (("position", n + 2),), tuple(estimate_names(axes))
    if topic == CORRECTION:
        return (("effort", n),), tuple(axes)
    if topic == COMMAND:
        return (("effort", 1),), (axis,)
    return (), None


def recorded_topics(axes, ccc_takes_state: bool = True, interpolator_takes_state: bool = False) -> list:
    """What the recorder takes: every lockstep topic, then /diagnostics (event-driven, not counted)."""
    recorders = tuple(full_name for node, _, full_name in catalogue.instances(axes)
                      if any(i.topic == catalogue.EVERY_TOPIC for i in node.inputs))
    return topics(axes, ccc_takes_state, interpolator_takes_state) + [
        Topic(DIAGNOSTICS, catalogue.TOPIC_TYPES[DIAGNOSTICS], "any node", recorders, every_step=False)]


def message_problem(topic: Topic, msg) -> str | None:
    """What is wrong with a decoded message of ``topic`` (wrong joint names, wrong array length, non-finite
    value), or None. A /reference message may carry preview points after its first (positions only)."""
    holder = msg
    if topic.names is not None:
        names = msg.joint_names if topic.type == "trajectory_msgs/msg/JointTrajectory" else msg.name
        if tuple(names) != topic.names:
            return f"joint names {list(names)}, expected {list(topic.names)}"
    if topic.type == "trajectory_msgs/msg/JointTrajectory":
        if not msg.points:
            return "no trajectory point"
        holder = msg.points[0]
        for j, ahead in enumerate(msg.points[1:], start=1):     # the reference preview: positions only
            if len(ahead.positions) != len(msg.joint_names) or not all(map(math.isfinite, ahead.positions)):
                return f"preview point {j} has positions {list(ahead.positions)}, expected {len(msg.joint_names)} " \
                       "finite values"
    for name, length in topic.layout:
        values = getattr(holder, name)
        if len(values) != length:
            return f"{name} has {len(values)} values, expected {length}"
        if not all(map(math.isfinite, values)):
            return f"{name} holds a non-finite value {list(values)}"
    return None


def step_to_stamp(k: int, sample_time_ns: int) -> tuple:
    """(sec, nanosec) of step k."""
    return divmod(k * sample_time_ns, 1_000_000_000)


def reference_from_msg(msg, n_axes: int):
    """The core Reference of one /reference message (works on rclpy and decoded bag messages)."""
    point = msg.points[0]
    pos, vel, acc = point.positions, point.velocities, point.accelerations
    return Reference(theta=pos[n_axes], theta_dot=vel[n_axes], theta_ddot=acc[n_axes],
                     position=np.asarray(pos[:n_axes], dtype=float), velocity=np.asarray(vel[:n_axes], dtype=float),
                     acceleration=np.asarray(acc[:n_axes], dtype=float))


def estimate_from_msg(msg, n_axes: int):
    """The core ContourEstimate of one /contour_error message."""
    values = msg.position
    return ContourEstimate(theta=values[n_axes + 1], vector=np.asarray(values[:n_axes], dtype=float),
                           signed=values[n_axes])


def estimate_names(axes) -> list:
    """JointState names of a /contour_error message."""
    return list(axes) + [CONTOUR_ERROR_NAME, FOOT_POINT_NAME]


def estimate_values(estimate) -> list:
    """JointState positions of a /contour_error message."""
    return [float(v) for v in estimate.vector] + [float(estimate.signed), float(estimate.theta)]


def parse_groups(groups, axes, source: str = "--group") -> list:
    """The grouped layout's groups: each a list of full node names (``x/plant`` or ``/x/plant``) in graph
    order. Every name must be a node of the graph for ``axes`` and in one group at most; a ConfigError in
    one line otherwise, naming ``source`` (the option or the experiment key the groups came from)."""
    every = node_names(axes)
    seen, out = set(), []
    for group in groups:
        names = [n.strip() for n in (group.split(",") if isinstance(group, str) else group) if n.strip()]
        if not names:
            raise ConfigError(f"{source}: an empty group (expected NODE,NODE,... e.g. x/plant,x/servo)")
        full = []
        for name in names:
            name = "/" + name.strip("/")
            if name not in every:
                raise ConfigError(f"{source}: {name} is not a node of this graph (its nodes: {', '.join(every)})")
            if name in seen:
                raise ConfigError(f"{source}: {name} is in two groups (a node runs in one process)")
            seen.add(name)
            full.append(name)
        out.append([n for n in every if n in full])
    return out
