"""The node catalogue: every node concern of the graph, once, in graph order.

Each entry names the node as experiment files do (its section is /<name>, or /<axis>/<name> for a per-axis
node), whether there is one per axis, its console script (``ros2 run contouring_ros <script>``), its class
as ``"module:Class"`` (nothing is imported to read it), the topics it takes and publishes, whether its
experiment-file section may be left out. What reads it:
setup.py (the console scripts), :mod:`contouring_ros.wire.graph` (node names, topics with their publisher and
subscribers, the node specs the runner and launch/contouring.launch.py start), :mod:`contouring_ros.experiment`
(the node sections of an experiment file), :mod:`contouring_ros.run.composed` (the classes of its one loop),
and tests/package/test_node_catalogue.py
(the node and topic tables of README.md, docs/ARCHITECTURE.md and graph.py's docstring).

Graph order is the order of a step: the interpolator, the plants, the estimator, the CCC, the servos, then
the recorder. The topics of the graph are the nodes' outputs in that order (then /diagnostics, which every
node publishes). Topic names are the graph's own (relative to its namespace); ``<axis>`` in a name stands
for an axis: a per-axis node's own axis, every axis of the experiment for any other node.

Standard library only: setup.py loads this file by path, without importing the package, numpy or rclpy.
"""
import importlib
from dataclasses import dataclass

AXIS = "<axis>"

CLOCK = "/clock"
REFERENCE = "/reference"
STATE = f"/{AXIS}/state"
CONTOUR_ERROR = "/contour_error"
CORRECTION = "/ccc/correction"
COMMAND = f"/{AXIS}/command"
DIAGNOSTICS = "/diagnostics"
EVERY_TOPIC = "*"       # an input of every topic of the graph (the recorder's)
#: what a pip install's node commands start with (see :attr:`Node.pip_script`)
PIP_SCRIPT_PREFIX = "contouring-ros-"

#: topic -> its ROS message type
TOPIC_TYPES = {
    CLOCK: "rosgraph_msgs/msg/Clock",
    REFERENCE: "trajectory_msgs/msg/JointTrajectory",
    STATE: "sensor_msgs/msg/JointState",
    CONTOUR_ERROR: "sensor_msgs/msg/JointState",
    CORRECTION: "sensor_msgs/msg/JointState",
    COMMAND: "sensor_msgs/msg/JointState",
    DIAGNOSTICS: "diagnostic_msgs/msg/DiagnosticArray",
}
#: how a node uses an input, in the order a topic lists its subscribers: the nodes whose step reads it,
#: then those it only paces, then those that record it undecoded (each in graph order)
USES = ("data", "pacing", "record")


@dataclass(frozen=True)
class Input:
    """One input of a node: the topic, how the node uses it (one of USES), and the flag of
    :func:`contouring_ros.wire.graph.topics` it depends on (None: always taken)."""

    topic: str
    use: str = "data"
    when: str | None = None


@dataclass(frozen=True)
class Node:
    """One node concern of the graph."""

    name: str
    console_script: str
    node_class: str                  # "module:Class", a LockstepNode
    inputs: tuple = ()               # Input
    outputs: tuple = ()              # topic names
    per_axis: bool = False           # one node per axis, /<axis>/<name>
    optional: bool = False           # its experiment-file section may be left out

    @property
    def module(self) -> str:
        """The node's module, run by ``python -m`` and by its console script."""
        return self.node_class.split(":")[0]

    @property
    def pip_script(self) -> str:
        """The command a pip install puts on the PATH for this node: ``contouring-ros-`` and the executable's
        name with dashes (plant -> contouring-ros-plant, contour_estimator -> contouring-ros-contour-estimator),
        a name no other package's command takes."""
        return PIP_SCRIPT_PREFIX + self.console_script.replace("_", "-")

    def entry_point(self, ros_layout: bool = True) -> str:
        """Its console_scripts entry point, as setup.py writes it: the ``ros2 run`` executable name for a
        colcon build (``ros_layout``; installed in lib/contouring_ros, off the PATH), else :attr:`pip_script`
        (a wheel's scripts go to the environment's bin/, on the PATH). contouring_ros.nodes.scripts imports
        the node's module when the script runs, so that a failed import is one line, not a traceback."""
        return f"{self.console_script if ros_layout else self.pip_script} = " \
               f"contouring_ros.nodes.scripts:{self.console_script}"

    def full_names(self, axes) -> list:
        """Fully qualified names of this concern's nodes in the graph of ``axes``."""
        return [f"/{axis}/{self.name}" for axis in axes] if self.per_axis else [f"/{self.name}"]


NODES = (
    Node("interpolator", "interpolator", "contouring_ros.nodes.interpolator:InterpolatorNode",
         inputs=(Input(CONTOUR_ERROR, "pacing"), Input(STATE, when="interpolator_takes_state")),
         outputs=(CLOCK, REFERENCE), optional=True),
    Node("plant", "plant", "contouring_ros.nodes.plant:PlantNode",
         inputs=(Input(COMMAND),), outputs=(STATE,), per_axis=True),
    Node("contour_estimator", "contour_estimator", "contouring_ros.nodes.contour_estimator:ContourEstimatorNode",
         inputs=(Input(REFERENCE), Input(STATE)), outputs=(CONTOUR_ERROR,)),
    Node("ccc", "ccc", "contouring_ros.nodes.ccc:CCCNode",
         inputs=(Input(CONTOUR_ERROR), Input(REFERENCE, when="ccc_takes_state"),
                 Input(STATE, when="ccc_takes_state")),
         outputs=(CORRECTION,)),
    Node("servo", "servo", "contouring_ros.nodes.servo:ServoNode",
         inputs=(Input(REFERENCE), Input(STATE), Input(CORRECTION)), outputs=(COMMAND,), per_axis=True),
    Node("recorder", "recorder", "contouring_ros.nodes.recorder:RecorderNode",
         inputs=(Input(EVERY_TOPIC, "record"),), optional=True),
)
#: name -> its Node
NODE = {node.name: node for node in NODES}
#: the names of the per-axis node concerns
PER_AXIS = frozenset(node.name for node in NODES if node.per_axis)


def on_axis(topic: str, axis: str) -> str:
    """The name of ``topic`` for ``axis`` (/<axis>/state, x -> /x/state; a topic of no axis as it is)."""
    return topic.replace(AXIS, axis)


def expand(topic: str, axes, own_axis: str | None = None) -> list:
    """The topics ``topic`` names in the graph of ``axes`` for a node of ``own_axis`` (None: not per axis):
    itself, its own axis' or every axis' topic."""
    if AXIS not in topic:
        return [topic]
    return [on_axis(topic, axis) for axis in ([own_axis] if own_axis is not None else axes)]


def instances(axes) -> list:
    """(Node, its axis or None, fully qualified name) of every node of the graph of ``axes``, graph order."""
    return [(node, axis, name) for node in NODES
            for axis, name in zip(axes if node.per_axis else [None], node.full_names(axes))]


def experiment_sections(axes) -> dict:
    """Section name -> node concern of an experiment file for ``axes``, in the order the validator names
    them: the required sections (per-axis ones first), then the optional ones."""
    ordered = sorted(NODES, key=lambda node: (node.optional, not node.per_axis))
    return {name: node.name for node in ordered for name in node.full_names(axes)}


def load_class(node: Node):
    """The class ``node.node_class`` names (imports its module)."""
    module, name = node.node_class.split(":")
    return getattr(importlib.import_module(module), name)


def doc_name(node: Node) -> str:
    """The node's name as the docs write it (/<axis>/plant, /ccc)."""
    return node.full_names([AXIS])[0]


def node_rows() -> list:
    """The docs' node table: (node, console script, input topics, output topics) of every node concern,
    topics as the docs write them (EVERY_TOPIC for the recorder's)."""
    return [(doc_name(node), node.console_script, tuple(dict.fromkeys(i.topic for i in node.inputs)),
             node.outputs) for node in NODES]


def topic_rows() -> list:
    """The docs' topic table: (topic, type, publisher) of every topic, graph order; /diagnostics last,
    published by every node."""
    rows = [(topic, TOPIC_TYPES[topic], doc_name(node)) for node in NODES for topic in node.outputs]
    return rows + [(DIAGNOSTICS, TOPIC_TYPES[DIAGNOSTICS], "every node")]


#: setup.py commands that build a wheel (pip's PEP 517/660 builds): their console scripts land on the PATH
WHEEL_COMMANDS = ("bdist_wheel", "editable_wheel", "dist_info")


def console_scripts(argv) -> list:
    """setup.py's console_scripts for a build run as ``argv``: under colcon (``setup.py install`` or
    ``develop``, scripts into lib/contouring_ros where ``ros2 run`` looks, off the PATH) each node's
    executable name; in a wheel (pip) the ``contouring-ros-<node>`` names, which cannot clash on the PATH
    with other packages' ``plant`` or ``servo``. The ``contouring-ros`` command line either way."""
    ros_layout = not any(command in argv for command in WHEEL_COMMANDS)
    return [node.entry_point(ros_layout) for node in NODES] + ["contouring-ros = contouring_ros.cli:main"]
