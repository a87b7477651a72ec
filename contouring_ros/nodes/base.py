"""The ground every node of the graph stands on: its rclpy node, parameters in, the validated experiment,
its inputs and outputs, /diagnostics, waiting for the rest of the graph and the end of the run.

How a node steps comes on top of this (:class:`~contouring_ros.nodes.node.LockstepNode`): what it admits of
its inputs (:mod:`.intake`), the lockstep loop (:mod:`.lockstep`) and the realtime loop (:mod:`.realtime`).

QoS, in one place: every graph topic is reliable, volatile, keep-all, so that no message is lost to the
recorder; nodes start publishing only once every expected subscriber has matched.
"""
from __future__ import annotations

import importlib
import sys
import time

import rclpy
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from ..wire import cdr, graph
from .rclpy_adapter import SubscriptionWaitSet, take_request, taker
from ..experiment.build import interpolator_takes_state
from ..experiment.validate import experiment_for_node
from .parameters import descriptor, node_parameters
from .explain import explain
from ..errors import ConfigError, RunError
from ..experiment.schema import GLOBAL_SECTION

__all__ = ["GRAPH_QOS", "DIAGNOSTICS_QOS", "message_class", "NodeBase"]

GRAPH_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE,
                       history=HistoryPolicy.KEEP_ALL, depth=1)
_DECODERS = {"sensor_msgs/msg/JointState": cdr.decode_joint_state,
             "trajectory_msgs/msg/JointTrajectory": cdr.decode_joint_trajectory}
DIAGNOSTICS_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE,
                             history=HistoryPolicy.KEEP_LAST, depth=100)
PROGRESS_PERIOD = 5.0    # s between a node's progress log lines
SERVICE_PERIOD = 0.1     # s at most between two turns answering the node's service requests (ros2 param)
ACK_TIMEOUT = 5.0        # s to wait for the last messages to be acknowledged


def message_class(type_name: str):
    """The Python class of 'pkg/msg/Type'."""
    package, _, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


class NodeBase:
    """A node of the graph without its stepping: parameters in, validated experiment, inputs and outputs.

    The stepping (:meth:`take_all`, :meth:`on_message`, :meth:`spin`, :meth:`spin_realtime` ...) and the
    realtime counters :meth:`finish` reports come from the mixins of
    :class:`~contouring_ros.nodes.node.LockstepNode`, the class the nodes subclass.
    """

    role = ""
    default_name = ""
    #: one node per axis, in the axis' namespace (the plant and the servo: /x/plant serves x)
    per_axis = False

    def __init__(self, args=None, *, name: str | None = None, namespace: str | None = None,
                 parameter_overrides=None, callbacks: bool = False):
        """Create the node. ``callbacks`` selects the stock path: inputs arrive through subscription
        callbacks of whatever executor spins ``self.node`` (for embedding and the composed layout)
        instead of the node's own wait-set loop (:meth:`spin`)."""
        self.callbacks = callbacks
        self._next_service_turn = 0.0   # monotonic time of the next turn answering service requests
        self.node = rclpy.create_node(name or self.default_name, namespace=namespace,
                                      parameter_overrides=parameter_overrides or [],
                                      automatically_declare_parameters_from_overrides=True)
        self.name = self.node.get_fully_qualified_name()
        #: the namespace of the graph this node belongs to: every topic is resolved under it
        self.graph_namespace = graph.graph_namespace(self.name, self.per_axis)
        parameters = {name: p.value for name, p in self.node.get_parameters_by_prefix("").items()}
        try:
            self.experiment = experiment_for_node(parameters, self.name, self.role)
        except ConfigError as error:      # said in the user's terms where the file or namespace is why
            why = explain(self.name, self.role, args if args is not None else sys.argv) \
                if "missing required key" in str(error) else None
            if why is None:
                raise
            raise ConfigError(why) from None
        self.declare_described(parameters)
        self.sample_time_ns = int(round(self.experiment.sample_time * 1e9))
        self.n_steps = self.experiment.n_steps
        self.axes = list(self.experiment.axes)
        self._topics = {t.name: t for t in graph.recorded_topics(
            self.axes, self.experiment.ccc_takes_state, interpolator_takes_state(self.experiment))}
        self._inputs = []          # (topic name, subscription, msg class, decoder)
        self._takers = []          # (topic name, the subscription's take: rclpy_adapter.taker)
        self._decoded_keys = {}    # input topic -> its key in intake._DECODED
        self._outputs = {}         # topic name -> publisher
        self._pending = {}         # step -> {topic: msg}
        self.rejected = {}         # topic -> count of rejected messages
        self._last_valid = {}      # topic -> last valid decoded message (for on_invalid_input: hold)
        self._sequence = {}        # topic -> publication sequence number expected of its one publisher
        self._last_step = {}       # topic -> step of the last message admitted
        self.strangers = 0         # messages refused before filing (wrong publisher, stamp, size)
        self.second_publisher = {}  # topic -> the step when a second writer's message was first seen
        self._diagnostics = self.node.create_publisher(DiagnosticArray, self.wire_name(graph.DIAGNOSTICS),
                                                       DIAGNOSTICS_QOS)
        self.next_step = 0
        self.finished = False
        self._realtime = self.experiment.timing == "realtime"
        self.setup()

    def declare_described(self, parameters: dict):
        """Declare every parameter of this node again, now with its descriptor (meaning and unit, range,
        read-only: :mod:`contouring_ros.nodes.parameters`), and the defaults the file left out, so that
        ``ros2 param describe`` and ``ros2 param get`` show what the node runs with."""
        for name, parameter in node_parameters(parameters, self.name, self.role, self.experiment).items():
            if self.node.has_parameter(name):
                self.node.undeclare_parameter(name)
            self.node.declare_parameter(name, parameter.value, descriptor(parameter))

    def serve_requests(self, now: float | None = None):
        """Answer the requests waiting at the node's services (the standard parameter services: `ros2 param
        list|describe|get|set`), at most every SERVICE_PERIOD seconds. The lean loops wait on the inputs
        alone (no executor takes the node's messages away from them), so they call this between steps."""
        now = time.monotonic() if now is None else now
        if now < self._next_service_turn:
            return
        self._next_service_turn = now + SERVICE_PERIOD
        for service in self.node.services:
            while True:
                request, header = take_request(service)
                if header is None:
                    break
                service.send_response(service.callback(request, service.srv_type.Response()), header)

    # -- wiring -----------------------------------------------------------------------------------
    def add_input(self, topic: str, qos=GRAPH_QOS, used: bool = True):
        """Subscribe to ``topic``; its messages reach :meth:`on_step` decoded by the cdr codec and checked.

        An input that is not ``used`` still paces the steps (a step fires once it is there too) but is
        neither decoded nor checked: :meth:`on_step` gets its serialised bytes.
        """
        type_name = self._topics[topic].type
        cls = message_class(type_name)
        callback = (lambda data, topic=topic: self.on_message(topic, data)) if self.callbacks else (lambda _: None)
        sub = self.node.create_subscription(cls, self.wire_name(topic), callback, qos, raw=True)
        self._inputs.append((topic, sub, cls, _DECODERS.get(type_name) if used else None))
        self._takers.append((topic, taker(sub, cls)))
        self._decoded_keys[topic] = self.decoded_key(topic)
        if self._topics[topic].every_step:
            # one publisher per graph topic, matched before it publishes (wait_for_graph), reliable and
            # keep-all: its messages reach us numbered 1, 2, 3 ... Any other number is another writer's.
            self._sequence[topic] = 1
        self._last_step[topic] = -1

    def add_output(self, topic: str):
        pub = self.node.create_publisher(message_class(self._topics[topic].type), self.wire_name(topic), GRAPH_QOS)
        self._outputs[topic] = pub
        return pub

    def subscriptions(self) -> list:
        """The subscriptions of the node's inputs, in the order they were added."""
        return [sub for _, sub, _, _ in self._inputs]

    def wait_set(self) -> SubscriptionWaitSet:
        """A persistent wait set over the node's inputs (one per loop, made once)."""
        return SubscriptionWaitSet(self.subscriptions(), self.node.context)

    def wire_name(self, topic: str) -> str:
        """The name on the wire of the graph's ``topic`` (/x/state is /m1/x/state under /m1)."""
        return graph.resolve(self.graph_namespace, topic, self.experiment.namespaced_clock)

    def decoded_key(self, topic: str) -> str:
        """The key of ``topic``'s messages among those decoded in this process (:data:`.intake._DECODED`): its name on
        the wire and what its messages must hold (one string, so that its hash is computed once)."""
        return f"{self.wire_name(topic)} {self._topics[topic]!r}"

    def own_axis(self) -> str:
        """The axis a per-axis node serves: the last part of its namespace (/x/plant and /m1/x/plant serve x)."""
        axis = self.name.strip("/").split("/")[-2] if self.name.count("/") > 1 else ""
        if axis not in self.axes:
            raise ConfigError(f"{self.name}: the namespace names axis {axis!r}, which is not in axes {self.axes}")
        return axis

    def stamp(self, k: int) -> tuple:
        """(sec, nanosec) of step k."""
        return graph.step_to_stamp(k, self.sample_time_ns)

    def reads_ahead(self, reader, what: str) -> int:
        """How many steps of reference ahead ``reader`` (a servo law or a controller: ``what`` in errors) reads
        (docs/ARCHITECTURE.md, "Reference preview"); refused unless the interpolator publishes as many."""
        preview = int(getattr(reader, "preview", 0) or 0)
        if preview > self.experiment.reference_preview:
            raise ConfigError(f"{self.name}: {what} reads {preview} steps of reference ahead but the interpolator "
                              f"publishes {self.experiment.reference_preview}: set {GLOBAL_SECTION}.reference_preview "
                              f"to {preview} or more (contouring-ros run sets it)")
        return preview

    def preview_points(self, k: int, message, count: int, what: str) -> list:
        """The ``count`` preview points of a /reference ``message`` (after its first); one line when it
        carries fewer."""
        points = message.points[1:1 + count]
        if len(points) < count:
            raise RunError(f"{self.name}: step {k}: /reference carries {len(message.points) - 1} preview points; "
                           f"{what} reads {count}")
        return points

    # -- to implement -----------------------------------------------------------------------------
    def setup(self):
        raise NotImplementedError

    def start(self):
        """Publish what the first step needs from this node before any input (default: nothing)."""

    def on_step(self, k: int, inputs: dict):
        raise NotImplementedError

    def counters(self) -> dict:
        """Node-specific counts for the end-of-run diagnostics (default: none)."""
        return {}

    # -- the graph and the end of the run ----------------------------------------------------------
    def wait_for_graph(self):
        """Block until every expected subscriber of our outputs and a publisher of every input matched.

        A publisher counts once it has shown itself: matched now or at an earlier look, or a message of it
        waits here. A node nobody waits for (the recorder) may look only after the publishers ran their
        steps, had them acknowledged by this process's middleware and left: their messages are here, the
        publishers are not.
        """
        timeout = self.experiment.graph_timeout
        deadline = time.monotonic() + timeout
        next_log = time.monotonic() + PROGRESS_PERIOD
        lockstep_inputs = [(index, topic, sub) for index, (topic, sub, _, _) in enumerate(self._inputs)
                           if self._topics[topic].every_step]
        inputs = self.wait_set() if lockstep_inputs else None
        shown = set()          # inputs whose publisher has shown itself
        # realtime: a node that comes up after the run's last tick waits no longer (a node that already
        # finished and left will never match)
        run_end = self.experiment.start_time + self.n_steps * self.experiment.sample_time \
            if self._realtime and self.experiment.start_time > 0.0 else None
        self.node.get_logger().info(f"waiting up to {timeout:g} s (graph_timeout) for the rest of the graph")
        while True:
            if not rclpy.ok(context=self.node.context):      # SIGINT/SIGTERM while waiting: stop now
                raise ExternalShutdownException()
            missing = [f"subscribers of {topic} ({', '.join(self._topics[topic].subscribers)})"
                       for topic, pub in self._outputs.items()
                       if pub.get_subscription_count() < len(self._topics[topic].subscribers)]
            holding = inputs.holding() if inputs is not None and len(shown) < len(lockstep_inputs) else []
            shown.update(topic for index, topic, sub in lockstep_inputs
                         if topic not in shown and (sub.get_publisher_count() >= 1 or holding[index]))
            missing += [f"the publisher of {topic}" for _, topic, _ in lockstep_inputs if topic not in shown]
            if not missing:
                self.node.get_logger().info(f"graph up: running {self.n_steps} steps ({self.experiment.timing})")
                return
            if time.monotonic() > deadline:
                raise RunError(f"{self.name}: the graph did not come up within {timeout:g} s (graph_timeout; "
                               f"still waiting for {missing[0]})")
            if time.monotonic() > next_log:
                next_log = time.monotonic() + PROGRESS_PERIOD
                self.node.get_logger().info(f"still waiting for {', '.join(missing)}")
            if run_end is not None and time.time() > run_end:
                raise RunError(f"{self.name}: the graph was not up by the realtime run's last tick (still waiting "
                               f"for {missing[0]}): the machine was too busy to start the graph in time")
            if not self.callbacks:
                self.serve_requests()
            time.sleep(0.01)


    def report(self, level, message: str, values: dict | None = None):
        """Publish one status of this node on /diagnostics (and log it)."""
        status = DiagnosticStatus(level=level, name=self.name, message=message, hardware_id="contouring_ros")
        status.values = [KeyValue(key=str(k), value=str(v)) for k, v in (values or {}).items()]
        array = DiagnosticArray(status=[status])
        array.header.stamp.sec, array.header.stamp.nanosec = self.stamp(self.next_step)
        self._diagnostics.publish(array)
        if level >= DiagnosticStatus.WARN:
            self.node.get_logger().warning(message)

    def current_step(self) -> int:
        """The step this node works on (the steps before it are done): what its progress, its end-of-run
        count and its refusals of strangers name."""
        return self.next_step


    def finish(self):
        """Wait until every subscriber still in the graph acknowledged what we published.

        A subscriber that left is no longer waited for (it leaves only after its last step). The end-of-run
        report on /diagnostics is waited for too: it is the node's last message, and a process that ends
        before its readers acknowledged it may take it with it. The acknowledgements follow the writers'
        heartbeats, every 20 ms with the package's Fast DDS profile.
        """
        steps = self.current_step()
        self.node.get_logger().info(f"completed {steps} steps")
        skipped = getattr(self, "skipped_ticks", 0)
        message = f"completed {steps} steps"
        if skipped:
            message += (f"; skipped {skipped} ticks that started more than max_lag "
                        f"({self.experiment.max_lag * 1e3:g} ms) late (on_overrun: skip)")
        counts = {"steps": steps, **self.counters(), **self.realtime_counters(),
                  **{f"rejected {topic}": count for topic, count in self.rejected.items()}}
        self.report(DiagnosticStatus.OK if not self.rejected and not skipped else DiagnosticStatus.WARN,
                    message, counts)
        deadline = time.monotonic() + ACK_TIMEOUT
        for pub in [*self._outputs.values(), self._diagnostics]:
            while time.monotonic() < deadline:
                if pub.get_subscription_count() == 0 or pub.wait_for_all_acked(Duration(nanoseconds=20_000_000)):
                    break
        self.check_single_publishers()

    def check_single_publishers(self):
        """Under ``on_invalid_input: hold``: a run whose node saw a second publisher on a graph topic (a
        message breaking the one writer's sequence numbers, or two writers matched at the end) does not end
        0. Message info carries no writer identity here: a stranger's message numbered as the graph's
        writer would number it cannot be told apart from the genuine one, so the steps may hold a stranger's
        message (the genuine one then refused); ``stop`` ends the run at the first such message."""
        if self.experiment.on_invalid_input != "hold":
            return
        seen = dict(self.second_publisher)
        for topic, sub, _, _ in self._inputs:
            if self._topics[topic].every_step and topic not in seen and sub.get_publisher_count() > 1:
                seen[topic] = f"the end ({sub.get_publisher_count()} publishers matched)"
        if seen:
            topic, where = next(iter(seen.items()))
            raise RunError(f"{self.name}: a second publisher of {topic} appeared ({where}; "
                           f"{self._topics[topic].publisher} is its only publisher in the graph): its messages "
                           "cannot be told apart from the graph's with certainty, so the run's results are not "
                           "trusted (on_invalid_input: hold); run on a domain of its own"
                           + (f" (also on {', '.join(list(seen)[1:])})" if len(seen) > 1 else ""))

    def destroy(self):
        self.node.destroy_node()

