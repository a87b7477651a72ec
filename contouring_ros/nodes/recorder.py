"""Recorder node: takes every topic of the graph undecoded and writes one MCAP bag.

The CDR payloads are written as they arrived; each message is logged at its step stamp (read from the
serialised header, without deserialising the message), so a bag's payloads are identical run to run. The
experiment's YAML is stored in the bag. The recorder stops once every topic has delivered all its steps;
on SIGINT/SIGTERM it closes the bag with its summary.

Only what the graph's own nodes published is recorded: a lockstep topic's messages must come from its one
publisher (publication sequence numbers 1, 2, 3 ...) with the stamps of steps 0, 1, 2 ... in order (in
realtime timing: increasing); /diagnostics messages must decode and carry a stamp within the run, at most
DIAGNOSTICS_LIMIT of them. Anything else is refused (:meth:`LockstepNode.refuse`): counted, reported on
/diagnostics, and with ``on_invalid_input: stop`` (the default) the recorder stops with an error, so a run
whose bag would be polluted never exits 0; with ``hold`` it is left out of the bag.
"""
from __future__ import annotations

import os
import time

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.serialization import deserialize_message

from .._version import __version__
from ..wire import cdr, graph
from ..records.bag_writer import EXPERIMENT_METADATA, RUN_METADATA, BagWriter
from ..experiment.build import interpolator_takes_state
from ..experiment.files import recorded_text
from ..errors import ConfigError
from .base import DIAGNOSTICS_QOS, GRAPH_QOS
from .node import LockstepNode
from .process import run_node

DIAGNOSTICS_LINGER = 0.3   # s the recorder keeps taking /diagnostics after the last lockstep message
REALTIME_GRACE = 2.0       # s after the last realtime tick the recorder waits for steps that never came
DIAGNOSTICS_LIMIT = 10_000  # /diagnostics messages recorded at most (each node sends a few per run)
PROGRESS_PERIOD = 0.2       # s between two writes of the progress file (graph.PROGRESS_ENV) while recording

class RecorderNode(LockstepNode):
    role = "recorder"
    default_name = "recorder"

    def setup(self):
        options = self.experiment.info["node"]
        if not options["bag"]:
            raise ConfigError(f"{self.name}: parameter 'bag' (the .mcap file to write) is required")
        text = recorded_text(options["experiment_file"]) if options["experiment_file"] else ""
        self.topic_list = graph.recorded_topics(
            self.axes, self.experiment.ccc_takes_state, interpolator_takes_state(self.experiment))
        for topic in self.topic_list:
            self.add_input(topic.name, GRAPH_QOS if topic.name != graph.DIAGNOSTICS else DIAGNOSTICS_QOS)
        self.counts = {topic.name: 0 for topic in self.topic_list}
        self.lockstep_topics = [topic.name for topic in self.topic_list if topic.every_step]
        self._incomplete = len(self.lockstep_topics)      # lockstep topics still short of n_steps messages
        self.first_receive = self.last_receive = None
        self.graph_nodes = {graph.resolve(self.graph_namespace, name) for name in graph.node_names(self.axes)}
        self._skip, self.foreign = False, 0       # other programs' /diagnostics messages, not recorded
        # channels carry the names on the wire (under the graph's namespace, as `ros2 bag record` would)
        self.channel_names = {t.name: self.wire_name(t.name) for t in self.topic_list}
        progress = os.environ.get(graph.PROGRESS_ENV)      # the runner's progress bar reads it
        self._progress_fd = os.open(progress, os.O_WRONLY) if progress and os.path.isfile(progress) else None
        self._progress_due = 0.0
        self.writer = BagWriter(options["bag"], [(self.channel_names[t.name], t.type) for t in self.topic_list],
                                background=True, metadata={
            EXPERIMENT_METADATA: {"yaml": text, "axes": ",".join(self.axes), "steps": str(self.n_steps),
                                  "sample_time": repr(self.experiment.sample_time), "namespace": self.graph_namespace,
                                  "contouring_ros_version": __version__}})

    def stamp_problem(self, topic, stamp, k, off_step):
        if topic == graph.DIAGNOSTICS:
            if self.counts[topic] >= DIAGNOSTICS_LIMIT:
                return f"more than {DIAGNOSTICS_LIMIT} messages (the recorder's limit for /diagnostics)"
            problem = (f"negative stamp {stamp} ns" if stamp < 0 else
                       f"stamp {stamp} ns is not on a step (sample time {self.sample_time_ns} ns)" if off_step else
                       f"stamp of step {k} is past the run's end (step {self.n_steps})" if k > self.n_steps else None)
            if problem is None:
                try:
                    deserialize_message(self._last_data, DiagnosticArray)
                except Exception as error:   # any malformed payload
                    problem = f"cannot be decoded ({type(error).__name__}: {error})"
            return problem
        if stamp < 0:
            return f"negative stamp {stamp} ns"
        if off_step:
            return f"stamp {stamp} ns is not on a step (sample time {self.sample_time_ns} ns)"
        if k >= self.n_steps:
            return f"stamp of step {k} is past the run's last step {self.n_steps - 1}"
        if self.experiment.timing == "realtime":
            if k <= self._last_step[topic]:
                return f"stamp of step {k} repeats or precedes step {self._last_step[topic]} already recorded"
        elif k != self.counts[topic]:
            return f"stamp of step {k} where step {self.counts[topic]} is next (steps come in order, once each)"
        return None

    def intake_problem(self, topic, data, sequence=None):
        self._last_data = data
        if topic == graph.DIAGNOSTICS and self._foreign_diagnostics(data):
            self._skip = True          # another program's diagnostics on the global topic: neither ours nor junk
            return None
        return super().intake_problem(topic, data, sequence)

    def _foreign_diagnostics(self, data) -> bool:
        """Whether a /diagnostics message is another program's: it decodes, and every status names a node
        that is not one of this graph's (/diagnostics is global, shared with every ROS program of the domain)."""
        try:
            array = deserialize_message(data, DiagnosticArray)
        except Exception:   # any malformed payload: not foreign, refused by the checks
            return False
        return bool(array.status) and not any(status.name in self.graph_nodes for status in array.status)

    def refuse(self, topic, problem, k=None):
        super().refuse(topic, problem, k)
        self.last_receive = time.monotonic()

    def on_message(self, topic, data):
        problem = self.intake_problem(topic, data)
        if problem is None:
            self.file_message(topic, data)
        else:
            self.refuse(topic, problem)

    def admitted(self, topic, data):
        self.file_message(topic, data)

    def current_step(self) -> int:
        """The steps recorded in full: every lockstep topic has its message of each step before this one (in
        realtime timing, where a step may be missing, has recorded a step at least this late)."""
        if self.experiment.timing == "realtime":
            return min(self._last_step[topic] for topic in self.lockstep_topics) + 1
        return min(self.counts[topic] for topic in self.lockstep_topics)

    def counters(self):
        return {"messages recorded": sum(self.counts.values()), "messages refused": self.strangers,
                "other programs' diagnostics left out": self.foreign}

    def file_message(self, topic, data):
        if self._skip:
            self._skip = False
            self.foreign += 1
            return
        self.writer.write(self.channel_names[topic], cdr.stamp_ns(data), data)
        self.counts[topic] += 1
        if self.counts[topic] == self.n_steps and topic in self.lockstep_topics:
            self._incomplete -= 1
        self.last_receive = time.monotonic()
        if self.first_receive is None:
            self.first_receive = self.last_receive
        if not self.finished and self.complete():
            self.finished = True
        if self._progress_fd is not None and (self.last_receive >= self._progress_due or self.finished):
            self._progress_due = self.last_receive + PROGRESS_PERIOD
            graph.write_progress(self._progress_fd, self.current_step())

    def complete(self) -> bool:
        return self._incomplete <= 0

    def spin(self):
        self.wait_for_graph()

        def take():
            before = sum(self.counts.values()) + self.strangers
            self.take_all()
            return sum(self.counts.values()) + self.strangers > before

        done, window = self.complete, None
        if self.experiment.timing == "realtime":
            # the graph is up well before tick 0 (the runner's start delay), and steps that never came are
            # waited for REALTIME_GRACE past the last tick: neither is a stall
            last_tick = self.experiment.start_time + self.n_steps * self.experiment.sample_time
            window = (self.experiment.start_time, last_tick)
            done = lambda: self.complete() or time.time() > last_tick + REALTIME_GRACE  # noqa: E731
        self.wait_loop(done, take,
                       lambda: "incomplete topics " + ", ".join(t for t in self.lockstep_topics
                                                                 if self.counts[t] < self.n_steps),
                       window=window)
        self.finished = True
        deadline = time.monotonic() + DIAGNOSTICS_LINGER      # the nodes' end-of-run summaries
        while time.monotonic() < deadline:
            self.take_all()
            time.sleep(0.01)

    def destroy(self):
        if self.first_receive is not None:
            self.writer.add_metadata(RUN_METADATA, {
                "wall_seconds_first_to_last_message": repr(self.last_receive - self.first_receive),
                "messages": str(sum(self.counts.values())), "messages refused": str(self.strangers),
                "complete": str(self.complete()).lower()})
        self.writer.close()
        if getattr(self, "_progress_fd", None) is not None:
            os.close(self._progress_fd)
            self._progress_fd = None
        super().destroy()


def main(args=None):
    raise SystemExit(run_node(RecorderNode, args))


if __name__ == "__main__":
    main()
