"""What the interpolator does each step on top of the feed plan: the in-position check at exact stops
(:class:`~contouring_ros.core.interpolation.InPositionClock`), feed hold and resume at the experiment's
events, and the controlled stop after a monitoring breach (:mod:`contouring_ros.core.monitoring`).

Feed hold (a control's feed hold key, LinuxCNC's pause): from the hold's step the reference leaves the plan
for a :class:`~contouring_ros.core.monitoring.ControlledStop` (a jerk-limited stop on the path within the
plan's bounds), and rests there. Resume: once the reference rests, at the resume's step or as soon as the
stop has ended, the rest of the path is planned afresh from rest at that point (the same feed plan over the
tool path from there on, :meth:`~contouring_ros.core.feed_planning.FeedPlan.rest_of_path`), with its own
in-position check at the exact stops still to come; the reference follows that plan.

The in-process loop and the interpolator node call :meth:`FeedControl.reference` for the steps in order
with the same axis states, so the graph gives the same references, bit for bit.
"""
from __future__ import annotations

from .interpolation import reference
from .monitoring import ControlledStop

__all__ = ["FeedControl", "parse_feed_events"]


def parse_feed_events(events, sample_time: float) -> list:
    """[(hold step, resume step or None), ...] of the experiment's ``feed_events`` (strings ``hold T`` and
    ``resume T``, T [s] ascending, a hold first and holds and resumes alternating); ValueError naming the
    entry otherwise."""
    out, expected, last = [], "hold", -1.0
    for entry in events:
        words = str(entry).split()
        if len(words) != 2 or words[0] not in ("hold", "resume"):
            raise ValueError(f"{entry!r}: expected 'hold T' or 'resume T' (T in seconds)")
        try:
            at = float(words[1])
        except ValueError:
            raise ValueError(f"{entry!r}: {words[1]!r} is not a time in seconds") from None
        if not at >= 0.0 or at <= last or at > 1e6:
            raise ValueError(f"{entry!r}: the times must rise from 0 (after {last:g} s)")
        if words[0] != expected:
            raise ValueError(f"{entry!r}: a {expected} comes next (holds and resumes alternate, a hold first)")
        step = int(round(at / sample_time))
        if words[0] == "hold":
            out.append([step, None])
        else:
            out[-1][1] = max(step, out[-1][0] + 1)
        expected, last = ("resume" if expected == "hold" else "hold"), at
    return [tuple(pair) for pair in out]


class FeedControl:
    """The reference of each step along a feed plan (module docstring).

    Parameters
    ----------
    curve, schedule :
        The tool path and its feed plan (a :class:`~contouring_ros.core.feed_planning.FeedPlan` where there
        are holds or a monitor).
    sample_time : float
    clock : InPositionClock or None
        The in-position clock of ``schedule`` (None: no in-position check).
    clock_for : callable or None
        ``clock_for(plan)``: the in-position clock of a plan resumed after a hold.
    monitor : Monitor or None
    holds : list
        (hold step, resume step or None) pairs, :func:`parse_feed_events`.
    delay : int
        The in-position check of step k sees the axis states of step k - delay (the node graph's interpolator
        publishes that far ahead).
    """

    def __init__(self, curve, schedule, sample_time: float, clock=None, clock_for=None, monitor=None, holds=(),
                 delay: int = 2):
        self.curve, self.sample_time, self.delay = curve, float(sample_time), int(delay)
        self.clock_for, self.monitor = clock_for, monitor
        self.holds = list(holds)
        self.plan, self.clock, self.origin = schedule, clock, 0
        self.last_time = 0.0            # plan time of the latest reference computed along the plan
        self.stop = None                # the ControlledStop under way or done (hold or breach)
        self.breached = False
        self.events = []                # (step, "hold" | "resume" | "stop", arc length): what happened when

    def reference(self, k: int, position=None, velocity=None):
        """The reference of step k (``position``, ``velocity``: the axis states the in-position check sees,
        those of step k - delay; None before the first)."""
        if self.monitor is not None and not self.breached and self.monitor.stopping(k):
            self.breached = True
            if self.stop is None:
                self._stop(k, "stop")
        if self.stop is not None and not self.breached and self.holds and self.holds[0][1] is not None and \
                k >= max(self.holds[0][1], self.stop.rest_step):
            self._resume(k)
        if self.stop is None and self.holds and k >= self.holds[0][0]:
            self._stop(k, "hold")
        if self.stop is not None:
            return self.stop.reference(k)
        local = k - self.origin
        if self.clock is None:
            t = local * self.sample_time
        else:
            t = self.clock.time(local, position, velocity)
        self.last_time = t
        return reference(self.curve, self.plan, t)

    def _stop(self, k: int, why: str) -> None:
        self.stop = ControlledStop(self.curve, self.plan, self.last_time, k, self.sample_time)
        self.events.append((k, why, self.stop.start))

    def _resume(self, k: int) -> None:
        rest = float(self.stop.reference(k).theta)
        self.holds.pop(0)
        plan = self.plan.rest_of_path(rest)
        if plan is None:                 # the stop ended at the program's end: nothing left to resume
            return
        self.events.append((k, "resume", rest))
        self.plan, self.stop, self.origin = plan, None, k
        self.clock = self.clock_for(plan) if self.clock_for and self.clock is not None else None
