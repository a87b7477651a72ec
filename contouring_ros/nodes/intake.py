"""What a node admits of its inputs, and how it reads them once admitted.

A serialised message taken from a subscription is admitted or refused before it is filed: refused when it
is not the topic's one publisher's (its publication sequence number), when it carries no stamp, or when its
stamp is off the steps, past the run, a repeat or too far ahead. A refused message is counted, reported on
/diagnostics and stops the run (``on_invalid_input: stop``) or is left out (``hold``). An admitted message is
decoded by the cdr codec and checked against its topic's layout when its step is handled; the nodes of one
process decode a message once (:data:`_DECODED`).
"""
from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticStatus

from ..wire import cdr, graph
from ..errors import RunError

__all__ = ["MAX_AHEAD", "REPORT_LIMIT", "InputIntake"]

#: how many steps past the one a node works on an input may be stamped: the graph's own nodes run at most
#: LOOKAHEAD + 1 steps apart, so this bounds every pending-step buffer (at most MAX_AHEAD + 1 steps held)
MAX_AHEAD = 64
REPORT_LIMIT = 20        # rejections reported on /diagnostics per topic; the rest are counted
_MIN_STAMPED = 12        # bytes of the smallest stamped message: encapsulation, sec, nanosec
#: the last message of each topic decoded in this process, by name on the wire and graph.Topic: (its bytes,
#: the decoded message, what is wrong with it or None). In the composed and grouped layouts several nodes of one process
#: take the same message (/reference reaches the estimator and every servo): it is decoded and checked once.
#: Decoded messages are read, never changed, by the nodes. One entry a topic.
_DECODED: dict = {}


class InputIntake:
    """Mixin of :class:`~contouring_ros.nodes.node.LockstepNode`: taking, admitting, refusing and decoding
    the inputs that :meth:`~contouring_ros.nodes.base.NodeBase.add_input` subscribed to (its ``_inputs``,
    ``_takers``, ``_sequence``, ``_last_step`` and ``_decoded_keys``)."""

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

