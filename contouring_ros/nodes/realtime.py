"""The realtime loop: nodes tick on the wall clock, every Ts from a shared start time, with the newest input
of each kind (docs/ARCHITECTURE.md, "Other timing modes").

One loop, :func:`realtime_loop`, ticks one node in its own process (:meth:`RealtimeStepping.spin_realtime`)
or a group of nodes in one thread (:mod:`contouring_ros.run.composed`), and applies the overrun policy
(:func:`overrun_message`); :func:`wait_until` waits for a tick taking what arrives; :func:`slow_tick_seconds`
is the overrun rehearsal knob.
"""
from __future__ import annotations

import gc
import os
import time

import numpy as np

import rclpy
from rclpy.executors import ExternalShutdownException

from ..wire import cdr
from ..errors import ConfigError, RunError

__all__ = ["SLOW_TICK_ENV", "COMPOSED_LOOP", "RealtimeStepping", "slow_tick_seconds", "realtime_loop",
           "overrun_message", "wait_until"]

SLOW_TICK_ENV = "CONTOURING_ROS_SLOW_TICK"   # overrun rehearsal: see slow_tick_seconds
COMPOSED_LOOP = "the composed loop"          # how the overrun error names the composed layout's one loop


class RealtimeStepping:
    """Mixin of :class:`~contouring_ros.nodes.node.LockstepNode`: a node's realtime ticks, the newest
    input of each kind held, and their timing counted for the end-of-run summary."""

    #: realtime: at tick k the node handles step k + realtime_offset (the plant, -1: at tick k it applies
    #: the command it holds over the last period and publishes its state at k)
    realtime_offset = 0
    #: realtime: whether a tick needs every input (False for the interpolator, whose input only paces it)
    realtime_needs_inputs = True

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
    its own process (:meth:`RealtimeStepping.spin_realtime`) or a group sharing one thread
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

