"""What the interpolator does each step on top of the feed plan: the in-position check at exact stops
(:class:`~contouring_ros.core.interpolation.InPositionClock`), feed hold and resume at the experiment's
events, feed override, and the controlled stop after a monitoring breach (:mod:`contouring_ros.core.monitoring`).

Feed hold (a control's feed hold key, LinuxCNC's pause): from the hold's step the reference leaves the plan
for a :class:`~contouring_ros.core.monitoring.ControlledStop` (a jerk-limited stop on the path within the
plan's bounds), and rests there. Resume: once the reference rests, at the resume's step or as soon as the
stop has ended, the rest of the path is planned afresh from rest at that point (the same feed plan over the
tool path from there on, :meth:`~contouring_ros.core.feed_planning.FeedPlan.rest_of_path`), with its own
in-position check at the exact stops still to come; the reference follows that plan.

Feed override (a control's override switch, 0 to 200 % of every programmed feed, rapids included, as the
schedule's ``feed_override``): while the tool moves, the rest of the path is planned afresh with the new
feeds from the state (arc length, feed and its rate) of the last reference given, so the feed and its rate
run on continuously and the new plan keeps the acceleration and jerk bounds (a feed above the new limits is
brought down within them first, the time-optimal jerk-limited way: Ruckig, as the feed plan). Where the
state cannot be left so (an in-position wait, a feed that cannot come down before the span's end) the
override acts at the first later step where it can. 0 % stops on the path as a hold does; the next override
above 0 % resumes. While stopped, an override sets the feeds the resume plans with.

The in-process loop and the interpolator node call :meth:`FeedControl.reference` for the steps in order
with the same axis states, so the graph gives the same references, bit for bit.
"""
from __future__ import annotations

from .interpolation import reference
from .monitoring import ControlledStop

__all__ = ["FeedControl", "parse_feed_events"]


#: the feed override an event may set [percent], as a control's override switch (LinuxCNC's MAX_FEED_OVERRIDE 2.0)
OVERRIDE_RANGE = (0.0, 200.0)


def parse_feed_events(events, sample_time: float) -> list:
    """[(step, what, value), ...] of the experiment's ``feed_events``: strings ``hold T``, ``resume T`` and
    ``override P% T`` (P in percent, 0 to 200, the % sign optional), T [s] rising; holds and resumes
    alternate, a hold first. ``value`` is the override's fraction (0.5 for 50%), None for a hold or a resume.
    ValueError naming the entry otherwise."""
    out, expected, last = [], "hold", -1.0
    for entry in events:
        words = str(entry).split()
        if not (len(words) == 2 and words[0] in ("hold", "resume") or len(words) == 3 and words[0] == "override"):
            raise ValueError(f"{entry!r}: expected 'hold T', 'resume T' or 'override P% T' (T in seconds, P in "
                             "percent)")
        try:
            at = float(words[-1])
        except ValueError:
            raise ValueError(f"{entry!r}: {words[-1]!r} is not a time in seconds") from None
        if not at >= 0.0 or at <= last or at > 1e6:
            raise ValueError(f"{entry!r}: the times must rise from 0 (after {last:g} s)")
        step, last = int(round(at / sample_time)), at
        if words[0] == "override":
            try:
                percent = float(words[1].removesuffix("%"))
            except ValueError:
                raise ValueError(f"{entry!r}: {words[1]!r} is not a percentage") from None
            if not OVERRIDE_RANGE[0] <= percent <= OVERRIDE_RANGE[1]:
                raise ValueError(f"{entry!r}: the feed override must be {OVERRIDE_RANGE[0]:g} to "
                                 f"{OVERRIDE_RANGE[1]:g} %")
            out.append((step, "override", percent / 100.0))
            continue
        if words[0] != expected:
            raise ValueError(f"{entry!r}: a {expected} comes next (holds and resumes alternate, a hold first)")
        if words[0] == "resume":
            held = next(event[0] for event in reversed(out) if event[1] == "hold")
            step = max(step, held + 1)
        out.append((step, words[0], None))
        expected = "resume" if expected == "hold" else "hold"
    return out


class FeedControl:
    """The reference of each step along a feed plan (module docstring).

    Parameters
    ----------
    curve, schedule :
        The tool path and its feed plan (a :class:`~contouring_ros.core.feed_planning.FeedPlan` where there
        are feed events or a monitor).
    sample_time : float
    clock : InPositionClock or None
        The in-position clock of ``schedule`` (None: no in-position check).
    clock_for : callable or None
        ``clock_for(plan)``: the in-position clock of a plan made during the run (a resume, an override).
    monitor : Monitor or None
    events : list
        (step, what, value) of :func:`parse_feed_events`, in order.
    delay : int
        The in-position check of step k sees the axis states of step k - delay (the node graph's interpolator
        publishes that far ahead).
    """

    def __init__(self, curve, schedule, sample_time: float, clock=None, clock_for=None, monitor=None, events=(),
                 delay: int = 2):
        self.curve, self.sample_time, self.delay = curve, float(sample_time), int(delay)
        self.clock_for, self.monitor = clock_for, monitor
        self.queue = list(events)        # the events still to come, in order
        self.plan, self.clock, self.origin = schedule, clock, 0
        self.override = float(getattr(schedule, "feed_override", 1.0))
        self.wanted = None              # an override not applied yet (the plan could not leave its state then)
        self.last_time = 0.0            # plan time of the latest reference computed along the plan
        self.stop = None                # the ControlledStop under way or done (hold, 0% override or breach)
        self.held = False               # a hold waits for its resume
        self.breached = False
        self.ended = False              # a stop that came to rest at the program's end: nothing to resume
        self.events = []                # (step, what, arc length): what happened when
        self.step = -1                  # the latest step whose reference was computed

    def command(self, what: str, percent: float | None = None) -> tuple:
        """A ``hold``, ``resume`` or ``override`` (``percent``) given while the run goes (the realtime
        interpolator's services and override topic): it acts as the same event of ``feed_events`` at the
        next step whose reference is computed. Returns (accepted, one line saying what or why not)."""
        k = self.step + 1
        if self.breached:
            return False, f"{what} refused: the run stopped on a monitoring breach"
        held = self.held if not any(event[1] in ("hold", "resume") for event in self.queue) else \
            [event[1] for event in self.queue if event[1] in ("hold", "resume")][-1] == "hold"
        value = None
        if what == "hold" and held:
            return False, "hold refused: the feed is held already"
        if what == "resume" and not held:
            return False, "resume refused: no feed hold to resume"
        if what == "override":
            if not (percent is not None and OVERRIDE_RANGE[0] <= percent <= OVERRIDE_RANGE[1]):
                return False, (f"feed override {percent} % refused: it must be {OVERRIDE_RANGE[0]:g} to "
                               f"{OVERRIDE_RANGE[1]:g} %")
            value = float(percent) / 100.0
        elif what not in ("hold", "resume"):
            raise ValueError(f"{what!r}: expected hold, resume or override")
        at = next((i for i, event in enumerate(self.queue) if event[0] > k), len(self.queue))
        self.queue.insert(at, (k, what, value))
        return True, f"{what}{'' if value is None else f' {percent:g}%'} at step {k}"

    def reference(self, k: int, position=None, velocity=None):
        """The reference of step k (``position``, ``velocity``: the axis states the in-position check sees,
        those of step k - delay; None before the first)."""
        self.step = k
        if self.monitor is not None and not self.breached and self.monitor.stopping(k):
            self.breached = True
            if self.stop is None:
                self._stop(k, "stop")
        while self.queue and self.queue[0][0] <= k:
            _, what, value = self.queue.pop(0)
            if what == "hold":
                self.held = True
                if self.stop is None:
                    self._stop(k, "hold")
            elif what == "resume":
                self.held = False
            else:
                self.wanted = value
        if self.wanted is not None:
            self._apply_override(k)
        if self.stop is not None and not (self.breached or self.held or self.ended) and self.override > 0.0 and \
                k >= self.stop.rest_step:
            self._resume(k)
        if self.stop is not None:
            return self.stop.reference(k)
        local = k - self.origin
        if self.clock is None:
            t = local * self.sample_time
        else:
            t = self.clock.time(local, position, velocity)
        self.last_time = t
        return reference(self.curve, self.plan, t)

    def _apply_override(self, k: int) -> None:
        """Set the wanted override: while stopped, for the resume; at 0 %, stop on the path as a hold does;
        while moving, re-plan the rest of the path from the state of the reference of step k - 1 with the new
        feeds (:meth:`~contouring_ros.core.feed_planning.FeedPlan.rest_of_path`). Where that state cannot
        be left within the bounds (the feed about to come to an exact stop, an in-position wait under way, a
        feed that cannot be brought down before the span's end), the override waits for a later step."""
        wanted = self.wanted
        if self.stop is not None or wanted == 0.0:
            self.override, self.wanted = wanted, None
            if self.stop is None:
                self._stop(k, f"override {wanted * 100:g}%")
            else:
                self.events.append((k, f"override {wanted * 100:g}%", float(self.stop.reference(k).theta)))
            return
        if self.clock is not None and self.clock.holding:
            return
        first = k == self.origin                     # no reference given along this plan yet
        s, v, a = (float(x) for x in self.plan(0.0 if first else self.last_time))
        try:
            plan = self.plan.rest_of_path(s, wanted, (v, a))
        except ValueError:
            return
        self.events.append((k, f"override {wanted * 100:g}%", s))
        self.override, self.wanted = wanted, None
        if plan is None:
            return
        self.plan, self.origin = plan, k if first else k - 1
        self.clock = self.clock_for(plan) if self.clock_for and self.clock is not None else None

    def _stop(self, k: int, why: str) -> None:
        self.stop = ControlledStop(self.curve, self.plan, self.last_time, k, self.sample_time)
        self.events.append((k, why, self.stop.start))

    def _resume(self, k: int) -> None:
        rest = float(self.stop.reference(k).theta)
        plan = self.plan.rest_of_path(rest, self.override)
        if plan is None:                 # the stop ended at the program's end: nothing left to resume
            self.ended = True
            return
        self.events.append((k, "resume", rest))
        self.plan, self.stop, self.origin = plan, None, k
        self.clock = self.clock_for(plan) if self.clock_for and self.clock is not None else None
