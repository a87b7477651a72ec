"""The lockstep loop: a node handles step k as soon as every input of step k is there.

A node declares its inputs (topics it needs for each step) and a step handler. The loop waits on one
persistent wait set, takes serialised messages directly from the subscriptions (no executor, no
callbacks, no rclpy message objects: :mod:`contouring_ros.wire.cdr` reads and writes the wire format), files
them by the step their header stamp names, and calls the handler for step k as soon as every input of
step k is there (docs/ARCHITECTURE.md, "One control step"). Nothing depends on wall-clock arrival order.
"""
from __future__ import annotations

import time

import rclpy
from rclpy.executors import ExternalShutdownException

from ..wire import cdr
from ..errors import RunError
from .base import PROGRESS_PERIOD

__all__ = ["LockstepStepping"]


class LockstepStepping:
    """Mixin of :class:`~contouring_ros.nodes.node.LockstepNode`: the steps filed by their stamps and
    handled in order, on the node's own wait-set loop (:meth:`spin`), the composed layout's lean loop
    (:meth:`admitted`) or an executor's subscription callbacks (:meth:`on_message`)."""

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

    def missing_inputs(self) -> list:
        """The inputs of the step this node works on that have not arrived yet."""
        have = self._pending.get(self.next_step, {})
        return [topic for topic, *_ in self._inputs if topic not in have]

    def wait_loop(self, done, take_progress, describe_stall, window=None):
        """Wait on the inputs' persistent wait set and take what arrives until ``done()``.

        ``take_progress()`` takes the ready messages and says whether anything moved on; after
        ``stall_timeout`` seconds (an experiment key) without progress the node gives up with
        ``describe_stall()`` as the reason. ``window``: the Unix times of a realtime run's first and last
        ticks; nothing is expected outside them, so the stall clock runs only inside.
        """
        wait_set = self.wait_set()
        last_progress = next_log = time.monotonic()
        first_tick, last_tick = window if window is not None else (0.0, float("inf"))
        quiet_end = last_progress + max(0.0, first_tick - time.time())
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
            elif (time.monotonic() - max(last_progress, quiet_end) > self.experiment.stall_timeout
                  and time.time() <= last_tick):
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

