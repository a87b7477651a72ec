"""The lean lockstep loop every node of the graph runs on.

A node declares its inputs (topics it needs for each step) and a step handler. The loop waits on one
persistent wait set, takes serialised messages directly from the subscriptions (no executor, no
callbacks, no rclpy message objects: :mod:`contouring_ros.wire.cdr` reads and writes the wire format), files
them by the step their header stamp names, and calls the handler for step k as soon as every input of
step k is there (docs/ARCHITECTURE.md, "One control step"). Nothing depends on wall-clock arrival order.

QoS, in one place: every graph topic is reliable, volatile, keep-all, so that no message is lost to the
recorder; nodes start publishing only once every expected subscriber has matched.
"""
from __future__ import annotations

import gc
import importlib
import os
import sys
import threading
import time

import numpy as np

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
from .explain import explain, help_text, wants_help
from ..errors import ConfigError, ContouringError, RunError
from ..experiment.schema import GLOBAL_SECTION

__all__ = ["GRAPH_QOS", "message_class", "LockstepNode", "run_node"]

GRAPH_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE,
                       history=HistoryPolicy.KEEP_ALL, depth=1)
_DECODERS = {"sensor_msgs/msg/JointState": cdr.decode_joint_state,
             "trajectory_msgs/msg/JointTrajectory": cdr.decode_joint_trajectory}
DIAGNOSTICS_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE,
                             history=HistoryPolicy.KEEP_LAST, depth=100)
PROGRESS_PERIOD = 5.0    # s between a node's progress log lines
SERVICE_PERIOD = 0.1     # s at most between two turns answering the node's service requests (ros2 param)
#: how many steps past the one a node works on an input may be stamped: the graph's own nodes run at most
#: LOOKAHEAD + 1 steps apart, so this bounds every pending-step buffer (at most MAX_AHEAD + 1 steps held)
MAX_AHEAD = 64
REPORT_LIMIT = 20        # rejections reported on /diagnostics per topic; the rest are counted
_MIN_STAMPED = 12        # bytes of the smallest stamped message: encapsulation, sec, nanosec
ACK_TIMEOUT = 5.0        # s to wait for the last messages to be acknowledged
SLOW_TICK_ENV = "CONTOURING_ROS_SLOW_TICK"   # overrun rehearsal: see slow_tick_seconds
COMPOSED_LOOP = "the composed loop"          # how the overrun error names the composed layout's one loop
#: the last message of each topic decoded in this process, by name on the wire and graph.Topic: (its bytes,
#: the decoded message, what is wrong with it or None). In the composed and grouped layouts several nodes of one process
#: take the same message (/reference reaches the estimator and every servo): it is decoded and checked once.
#: Decoded messages are read, never changed, by the nodes. One entry a topic.
_DECODED: dict = {}


def message_class(type_name: str):
    """The Python class of 'pkg/msg/Type'."""
    package, _, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


class LockstepNode:
    """Base of the graph's nodes: parameters in, validated experiment, lockstep loop.

    Subclasses set ``role``, call :meth:`add_input` / :meth:`add_output` in ``setup`` and implement
    :meth:`start` (publish what needs no input) and :meth:`on_step` (handle one complete step).
    """

    role = ""
    default_name = ""
    #: realtime: at tick k the node handles step k + realtime_offset (the plant, -1: at tick k it applies
    #: the command it holds over the last period and publishes its state at k)
    realtime_offset = 0
    #: realtime: whether a tick needs every input (False for the interpolator, whose input only paces it)
    realtime_needs_inputs = True
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
        self._decoded_keys = {}    # input topic -> its key in _DECODED
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
        """The key of ``topic``'s messages among those decoded in this process (:data:`_DECODED`): its name on
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

    # -- the loop ---------------------------------------------------------------------------------
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

    def take_all(self, handle=None):
        """Take every message waiting on the inputs and pass each to ``handle(topic, data)``
        (default :meth:`file_message`; the composed layout passes :meth:`on_message`)."""
        handle = handle or self.file_message
        for topic, take in self._takers:
            while True:
                taken = take()
                if taken is None:
                    break
                data = taken[0]
                problem = self.intake_problem(topic, data, taken[1].get("publication_sequence_number"))
                if problem is None:
                    handle(topic, data)
                else:
                    self.refuse(topic, problem)

    def intake_problem(self, topic: str, data: bytes, sequence=None):
        """Why a serialised message of ``topic`` cannot be filed, or None (and then it is admitted: the
        topic's expected sequence number and last step move on). A few microseconds a message.

        Refused: a message from a publisher other than the topic's one (its publication sequence number
        breaks the 1, 2, 3 ... of the one writer), a payload too short for a stamp, a stamp that is
        negative, between two steps, past the run's end, not after the topic's previous one (a duplicate or
        a past step), or more than MAX_AHEAD steps ahead of the step this node works on.
        """
        expected = self._sequence.get(topic)
        if expected is not None and sequence is not None and sequence != expected:
            shared = topic in graph.GLOBAL_TOPICS and self.graph_namespace != "/" and \
                not self.experiment.namespaced_clock
            return (f"a message from an unexpected publisher (publication sequence number {sequence}, expected "
                    f"{expected} from the topic's one publisher {self._topics[topic].publisher}; a second publisher "
                    f"wrote on {topic}: which messages are whose cannot be told with certainty)"
                    + (f"; {topic} is global under a namespace: graphs sharing a domain need namespaced_clock: true"
                       if shared else ""))
        if len(data) < _MIN_STAMPED:
            return f"a {len(data)}-byte payload cannot be decoded (no header stamp)"
        stamp = cdr.stamp_ns(data)
        k, off_step = divmod(stamp, self.sample_time_ns)
        problem = self.stamp_problem(topic, stamp, k, off_step)
        if problem is not None:
            return problem
        if expected is not None and sequence is not None:
            self._sequence[topic] = expected + 1
        self._last_step[topic] = k
        return None

    def stamp_problem(self, topic: str, stamp: int, k: int, off_step: int):
        """What is wrong with the stamp of a message of ``topic`` (step ``k``), or None."""
        if stamp < 0:
            return f"negative stamp {stamp} ns"
        if off_step:
            return f"stamp {stamp} ns is not on a step (sample time {self.sample_time_ns} ns)"
        if k >= self.n_steps + (not self._topics[topic].every_step):
            return f"stamp of step {k} is past the run's last step {self.n_steps - 1}"
        if self._topics[topic].every_step and k <= self._last_step[topic]:
            return f"stamp of step {k} repeats or precedes step {self._last_step[topic]} already taken"
        if k > self.next_step + MAX_AHEAD and not self._realtime:   # realtime holds one message a topic
            return (f"stamp of step {k} is too far ahead of step {self.next_step} (more than {MAX_AHEAD} steps: "
                    "the pending-step buffer is bounded)")
        return None

    def refuse(self, topic: str, problem: str, k: int | None = None):
        """An input that cannot be used: count it, report it on /diagnostics, and stop the run
        (``on_invalid_input: stop``) or go on without it (``hold``)."""
        self.rejected[topic] = self.rejected.get(topic, 0) + 1
        self.strangers += k is None
        where = f"step {self.current_step() if k is None else k}"
        if k is None and problem.startswith("a message from an unexpected publisher"):
            self.second_publisher.setdefault(topic, where)
        count = self.rejected[topic]
        if count <= REPORT_LIMIT:     # bounded: a flood of junk cannot flood /diagnostics (counted in finish)
            more = f" (further rejections on {topic} are only counted)" if count == REPORT_LIMIT else ""
            self.report(DiagnosticStatus.ERROR, f"{where}: rejected {topic}: {problem}{more}")
        if self.experiment.on_invalid_input == "stop" or (k is not None and topic not in self._last_valid):
            raise RunError(f"{self.name}: {where}: rejected {topic}: {problem}")

    def file_message(self, topic: str, data: bytes):
        """File a serialised (admitted) input under the step its stamp names."""
        k = cdr.stamp_ns(data) // self.sample_time_ns
        if k >= self.next_step:
            self._pending.setdefault(k, {})[topic] = data

    def on_message(self, topic: str, data: bytes):
        """Subscription callback of the stock executor path: file the message, run the steps it completes.
        (No message info here: the stamp checks apply, the publisher check does not.)"""
        problem = self.intake_problem(topic, data)
        if problem is None:
            self.file_message(topic, data)
            self._fire_ready_steps()
        else:
            self.refuse(topic, problem)

    def admitted(self, topic: str, data: bytes):
        """Lean composed path: ``take_all`` checked the message already; file it and fire."""
        self.file_message(topic, data)
        self._fire_ready_steps()

    def _fire_ready_steps(self) -> bool:
        """Handle every step whose inputs are complete; say whether at least one was handled."""
        n_inputs = len(self._inputs)
        first = self.next_step
        while not self.finished:
            ready = self._pending.get(self.next_step)
            if ready is None or len(ready) < n_inputs:
                break
            del self._pending[self.next_step]
            self.on_step(self.next_step, self._checked_inputs(self.next_step, ready))
            self.next_step += 1
            if self.next_step >= self.n_steps:
                self.finished = True
        return self.next_step > first

    def _checked_inputs(self, k: int, ready: dict) -> dict:
        """Decode step k's inputs and check each against its topic's layout.

        A malformed or non-finite message stops the run (``on_invalid_input: stop``, the default) or is
        replaced by the last valid message of its topic (``hold``, zero-order hold); either way it is
        reported on /diagnostics and counted. The nodes of one process share the work: a message another
        node of this process decoded already (the same bytes on the same topic) is not decoded again
        (:data:`_DECODED`).
        """
        inputs = {}
        for topic, _, _, decode in self._inputs:
            data = ready[topic]
            if decode is None:
                inputs[topic] = data
                continue
            key = self._decoded_keys[topic]
            last = _DECODED.get(key)
            if last is not None and last[0] == data:
                msg, problem = last[1], last[2]
            else:
                try:
                    msg = decode(data)
                except Exception as error:  # any malformed payload: struct, index, unicode, memory errors
                    msg, problem = None, f"cannot be decoded ({type(error).__name__}: {error})"
                else:
                    problem = graph.message_problem(self._topics[topic], msg)
                _DECODED[key] = (data, msg, problem)
            if problem is not None:
                self.refuse(topic, problem, k)
                msg = self._last_valid[topic]
            else:
                self._last_valid[topic] = msg
            inputs[topic] = msg
        return inputs

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

    def missing_inputs(self) -> list:
        have = self._pending.get(self.next_step, {})
        return [topic for topic, *_ in self._inputs if topic not in have]

    def wait_loop(self, done, take_progress, describe_stall):
        """Wait on the inputs' persistent wait set and take what arrives until ``done()``.

        ``take_progress()`` takes the ready messages and says whether anything moved on; after
        ``stall_timeout`` seconds (an experiment key) without progress the node gives up with
        ``describe_stall()`` as the reason.
        """
        wait_set = self.wait_set()
        last_progress = next_log = time.monotonic()
        while not done():
            wait_set.wait(200_000_000)
            self.serve_requests()
            if time.monotonic() >= next_log + PROGRESS_PERIOD:
                next_log = time.monotonic()
                self.node.get_logger().info(f"step {self.current_step()} of {self.n_steps}")
            if not rclpy.ok(context=self.node.context):
                raise ExternalShutdownException()
            if take_progress():
                last_progress = time.monotonic()
            elif time.monotonic() - last_progress > self.experiment.stall_timeout:
                raise RunError(f"{self.name}: stalled: {describe_stall()} for {self.experiment.stall_timeout:g} s")

    def spin(self):
        """Run the lockstep loop until the last step has been handled."""
        self.wait_for_graph()
        self.start()
        if not self._inputs:
            return

        def take_and_fire():
            self.take_all()
            return self._fire_ready_steps()

        self.wait_loop(lambda: self.finished, take_and_fire,
                       lambda: f"at step {self.next_step}, no message on {', '.join(self.missing_inputs())}")

    # -- realtime ---------------------------------------------------------------------------------------
    def realtime_setup(self):
        """Prepare the realtime tick counters; return the first tick this node handles."""
        if self.experiment.start_time <= 0.0:
            raise ConfigError(f"{self.name}: timing: realtime needs start_time (the shared Unix time of tick 0, "
                              "which contouring-ros run sets)")
        self._newest = {}
        self._first_tick = max(0, -self.realtime_offset)
        ticks = self.n_steps - self._first_tick
        self.latency, self.lateness = np.full(ticks, np.nan), np.full(ticks, np.nan)
        self.work = np.full(ticks, np.nan)
        self.deadline_misses = self.late_inputs = self.missing_inputs_count = self.skipped_ticks = 0
        self._extra_work = slow_tick_seconds(self.name)
        if self._extra_work:
            self.node.get_logger().warning(f"{SLOW_TICK_ENV}: every tick takes {self._extra_work * 1e3:g} ms "
                                           "longer (an overrun rehearsal)")
        return self._first_tick

    @property
    def first_tick(self) -> int:
        """The first realtime tick this node handles (set by :meth:`realtime_setup`)."""
        return self._first_tick

    def keep_newest(self, topic: str, data: bytes):
        """Realtime input handler: hold the newest message of each input (zero-order hold)."""
        k = cdr.stamp_ns(data) // self.sample_time_ns
        if topic not in self._newest or k >= self._newest[topic][0]:
            self._newest[topic] = (k, data)

    def tick_time(self, tick: int) -> float:
        """Wall-clock time at which this node handles ``tick``."""
        return self.experiment.start_time + tick * self.experiment.sample_time

    def realtime_tick(self, tick: int):
        """Handle tick ``tick`` now with the newest inputs held, and account for its timing."""
        if tick < self._first_tick:
            return
        self.take_all(self.keep_newest)
        deadline = self.tick_time(tick)
        woke = time.time()
        step, newest = tick + self.realtime_offset, self._newest
        present = [topic for topic, *_ in self._inputs if topic in newest]
        self.late_inputs += sum(1 for topic in present if newest[topic][0] < step - 1)
        if self.realtime_needs_inputs and len(present) < len(self._inputs):
            self.missing_inputs_count += 1
        else:
            self.on_step(step, self._checked_inputs(step, {topic: newest[topic][1] for topic in present})
                         if self.realtime_needs_inputs else {})
        if self._extra_work:
            time.sleep(self._extra_work)
        done = time.time()
        self.next_step = step + 1
        i = tick - self._first_tick
        self.lateness[i], self.latency[i], self.work[i] = woke - deadline, done - deadline, done - woke
        if done - deadline > self.experiment.sample_time:
            self.deadline_misses += 1
        if tick == self.n_steps - 1:
            self.finished = True

    def spin_realtime(self):
        """Tick on the wall clock every Ts from the experiment's ``start_time`` (docs/ARCHITECTURE.md, "Other timing modes"): at
        tick k take whatever arrived, hold the newest message of each input (zero-order hold) and handle
        step k + ``realtime_offset`` with them. A tick that starts late is still handled, at once, so every
        step is published; it counts as a deadline miss when its outputs leave after the next tick. An input
        older than the previous step counts as late, a tick without some input as missing (nothing is
        published for it). A tick that starts more than ``max_lag`` late trips :func:`realtime_loop`'s
        overrun policy."""
        self.wait_for_graph()
        self.start()
        self.realtime_setup()
        realtime_loop([self], self.name, self.wait_set(), lambda: self.take_all(self.keep_newest),
                      after_tick=self.serve_requests)

    def realtime_counters(self) -> dict:
        """Deadline misses, skipped ticks (``on_overrun: skip``), late and missing inputs, loop latency (tick
        to outputs sent) p50/p99/max, work time (the node's own handling of a tick) p50/p99 and wake-up
        jitter, in microseconds: the end-of-run realtime summary."""
        if getattr(self, "latency", None) is None or not np.isfinite(self.latency).any():
            return {}
        latency = self.latency[np.isfinite(self.latency)] * 1e6
        work = self.work[np.isfinite(self.work)] * 1e6
        return {"ticks": latency.size, "deadline misses": self.deadline_misses, "skipped ticks": self.skipped_ticks,
                "late inputs": self.late_inputs, "ticks missing an input": self.missing_inputs_count,
                "latency p50 [us]": f"{np.percentile(latency, 50):.0f}",
                "latency p99 [us]": f"{np.percentile(latency, 99):.0f}", "latency max [us]": f"{latency.max():.0f}",
                "work p50 [us]": f"{np.percentile(work, 50):.0f}", "work p99 [us]": f"{np.percentile(work, 99):.0f}",
                "jitter [us]": f"{np.std(self.lateness[np.isfinite(self.lateness)]) * 1e6:.0f}"}

    def recent_work(self, ticks: int = 100) -> float:
        """Mean work time per tick (s) over the last ``ticks`` ticks handled (0 before any)."""
        done = self.work[np.isfinite(self.work)][-ticks:]
        return float(done.mean()) if done.size else 0.0

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


def slow_tick_seconds(name: str) -> float:
    """Extra seconds each realtime tick of node ``name`` takes, from the environment variable SLOW_TICK_ENV
    ("NODE=SECONDS[,NODE=SECONDS ...]", e.g. "/x/servo=0.005"; 0 for a node it does not name). A rehearsal
    knob: it makes a node too slow for its ticks on purpose, so that the overrun policy can be seen (and
    tested) to act; it is never set by the package itself."""
    for item in os.environ.get(SLOW_TICK_ENV, "").split(","):
        node, _, seconds = item.partition("=")
        if node.strip() and "/" + node.strip().strip("/") == name:
            try:
                return max(0.0, float(seconds))
            except ValueError:
                raise ConfigError(f"{SLOW_TICK_ENV}: {item!r} is not NODE=SECONDS") from None
    return 0.0


def realtime_loop(nodes, label: str, wait_set, take, spin: float = 0.0, after_tick=None, idle=None):
    """Tick ``nodes`` on the wall clock, in order, every Ts from the experiment's ``start_time``: one node in
    its own process (:meth:`LockstepNode.spin_realtime`) or a group sharing one thread
    (:mod:`contouring_ros.run.composed`). Between ticks wait on ``wait_set`` (a
    :class:`~contouring_ros.nodes.rclpy_adapter.SubscriptionWaitSet`) and ``take()`` what arrives; after
    each tick call ``after_tick()``. ``label`` names the loop in the overrun error. ``idle``, a threading.Event,
    is set while the loop waits for its next tick and cleared while it ticks (:func:`wait_until`).

    Overrun policy: the loop knows its lag, how late a tick starts. Past ``max_lag`` (a shared key) it
    either stops the run with one line naming the loop, its lag and the step (``on_overrun: stop``, the
    default: like a drive's following-error trip, never a silent drift), or jumps to the tick now due and
    counts the ticks it skipped on every node (``on_overrun: skip``; reported at the end and on
    /diagnostics). The garbage collector's generations are frozen before the first tick (``gc.freeze``).
    """
    experiment = nodes[0].experiment
    context = nodes[0].node.context
    # everything allocated so far (modules, nodes, the core objects) leaves the collector's generations:
    # a full collection over it stalls a tick 10-20 ms on this machine, after the freeze about nothing
    gc.collect()
    gc.freeze()
    first = tick = min(node.first_tick for node in nodes)
    while tick < experiment.n_steps:
        due = nodes[0].tick_time(tick)
        wait_until(due, wait_set, take, context, spin=spin, idle=idle)
        lag = time.time() - due
        if lag > experiment.max_lag:
            if experiment.on_overrun == "stop":
                raise RunError(overrun_message(nodes, label, tick, lag, start=tick == first))
            now = min(int((time.time() - experiment.start_time) / experiment.sample_time), experiment.n_steps - 1)
            for node in nodes:
                node.skipped_ticks += max(0, now - max(tick, node.first_tick))
            tick = max(tick, now)
        for node in nodes:
            node.realtime_tick(tick)
        if after_tick is not None:
            after_tick()
        tick += 1


def overrun_message(nodes, label: str, tick: int, lag: float, start: bool = False) -> str:
    """The one line of an overrun trip (``on_overrun: stop``); ``start``: the loop's first tick was late
    already (the graph came up after its ``start_time``)."""
    experiment = nodes[0].experiment
    if start:
        return (f"{label} came up {lag:.2f} s after its first tick at step {tick} (start_time; max_lag "
                f"{experiment.max_lag * 1e3:g} ms): the machine was too busy to start the graph in time; try "
                "--composed or a grouping (--group: fewer processes to start), or timing: lockstep")
    busiest = ""
    if len(nodes) > 1:
        node = max(nodes, key=lambda n: n.recent_work())
        busiest = f"; most work per tick: {node.name}, {node.recent_work() * 1e3:.2f} ms"
    remedy = "timing: lockstep" if label == COMPOSED_LOOP else "--composed, a grouping (--group), or timing: lockstep"
    return (f"{label} fell {lag * 1e3:.1f} ms behind its ticks at step {tick} (max_lag "
            f"{experiment.max_lag * 1e3:g} ms{busiest}): the machine cannot keep up; try {remedy}")


def wait_until(deadline: float, wait_set, take, context, spin: float = 0.0, idle=None):
    """Until the wall clock reaches ``deadline``, wait on the subscriptions of ``wait_set`` (a
    :class:`~contouring_ros.nodes.rclpy_adapter.SubscriptionWaitSet`; None or one without subscriptions: sleep) and
    ``take()`` what arrives.

    With ``spin`` > 0 the last ``spin`` seconds are busy-waited (taking what arrives), so the return is not
    late by a timed wait's wake-up latency (about 0.1 ms here) at the cost of that much CPU per call.
    ``idle`` (a threading.Event) is set while the thread blocks in the wait, for work that should run only
    then (the composed layout's bag writer thread).
    """
    inputs = bool(wait_set)
    while True:
        remaining = deadline - time.time()
        if remaining <= 0.0:
            return
        if remaining <= spin:
            if inputs:
                take()
        elif inputs:
            if idle is not None:
                idle.set()
            wait_set.wait(int((remaining - spin) * 1e9))
            if idle is not None:
                idle.clear()
            take()
        else:
            time.sleep(remaining - spin)
        if not rclpy.ok(context=context):
            raise ExternalShutdownException()


def track_signals() -> list:
    """A list that receives the number of each SIGINT and SIGTERM that arrives (the handlers are installed
    before rclpy.init: rclpy's own handlers shut the context down and then call these), so that the exit
    code can tell an interruption, and which, from an error. SIGINT still raises KeyboardInterrupt."""
    import signal
    received = []

    def on_sigint(signum, frame):
        received.append(signum)
        raise KeyboardInterrupt

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, lambda signum, frame: received.append(signum))
        signal.signal(signal.SIGINT, on_sigint)
    return received


def interrupted_code(error: BaseException, received: list) -> int | None:
    """143 (SIGTERM) or 130 (SIGINT) when ``error`` is how an interruption ended a node's process (whatever
    the interrupted call raised once rclpy's handler had shut the context down: KeyboardInterrupt,
    ExternalShutdownException, an RCLError of a publisher whose context is gone), else None."""
    import signal
    if not received and not isinstance(error, ContouringError):
        time.sleep(0.01)          # a signal whose Python handler has not run yet runs now (sleep lets it in)
    if signal.SIGTERM in received:
        return 143
    if received or isinstance(error, (KeyboardInterrupt, ExternalShutdownException)):
        return 130
    if not isinstance(error, ContouringError) and not rclpy.ok():
        return 130                # the context is gone: a signal's handler shut it down
    return None


def run_node(node_class, args=None) -> int:
    """Entry point shared by every node's main(): init, spin to the end, clean shutdown.

    Returns the process exit code: 0 when the run completed, 1 on an error (reported in one line), 130 when
    interrupted by SIGINT and 143 by SIGTERM, in any state (waiting for the graph, stepping, finishing),
    without a traceback.
    """
    if wants_help(sys.argv if args is None else args):
        print(help_text(node_class.role))
        return 0
    received = track_signals()
    node = None
    code = 0
    try:
        rclpy.init(args=args)
        node = node_class(args)
        if node.experiment.timing == "realtime" and node.role != "recorder":
            node.spin_realtime()
        else:
            node.spin()
        node.finish()
    except BaseException as error:   # every way out becomes an exit code; only a bug keeps its traceback
        code = interrupted_code(error, received)
        if code is None and isinstance(error, ContouringError):
            print(f"error: {error}", file=sys.stderr)
            code = 1
        elif code is None:
            raise
    finally:
        try:
            if node is not None:
                node.destroy()
        except Exception:          # a node whose context a signal shut down: what matters (the bag) is closed
            if code == 0:
                raise
        rclpy.try_shutdown()
    return code
