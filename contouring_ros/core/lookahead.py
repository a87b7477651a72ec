"""The look-ahead window's backward pass, carried from one window to the next: the speeds from which the spans
in sight can still be brought to a stop at the window's end, and the plan a span's exit speed follows when
the latest window's cannot be reached.

Span i's exit speed is fixed when its entry is, from the spans beginning within the W blocks ahead of its
start, the last taken to end in a stop (step 3 of :mod:`.feed_planning`'s docstring): the backward pass runs
from that stop to boundary i + 1, each boundary's speed the lower of its corner speed and what
:func:`~.scurve.reach` can brake from to the next boundary's within the span. Two things make that
less simple than the passes over a whole program:

- Cost. A new window moves the stop by one span, and the pass from there back over every span in the window
  is W reach calls per span: on a program of short chords at distinct corner speeds (a CAM program's
  rounded coordinates make every chord its own span) that is W calls per block. The pass is carried over
  instead: going back from the new stop it ends where a boundary's speed comes out bit for bit as the last
  window's (it then is so all the way back, every input below being the same), which is within the braking
  distance of the stop wherever a corner caps the speed.
- A jerk-limited change of speed that starts and ends at zero acceleration is not monotone in its distance
  (from v, slowing to v / 3 takes more room than slowing to rest), so reach is not monotone in its start:
  a window that sees further can allow a slightly lower speed at a boundary than the window before, one span
  i cannot slow down to from the entry that window fixed. Then span i follows the plan the entry was fixed
  from (its speeds kept as the later windows overwrite them), which still ends in a stop within what was
  seen; the latest window's plan is taken again at the first boundary it can be reached from.
"""
from __future__ import annotations

from .scurve import SPARE, reach

__all__ = ["WindowChain"]


class WindowChain:
    """The backward pass of the latest look-ahead window, and the plan the feed follows.

    Spans are numbered from 0 in the order planned; boundary j is where span j begins (its corner speed).
    The caller gives each span's data as it comes into sight (:meth:`add`) and asks for one span's exit
    speed at a time (:meth:`exit_speed`), in order; what lies behind the span asked for is forgotten.
    """

    def __init__(self):
        self._span = {}          # span j -> (corner speed at its start, its start, acceleration, jerk)
        self._chain = {}         # boundary j -> the latest window's speed there (boundaries i + 1 .. its stop)
        self._kept = {}          # boundary j -> the followed plan's speed where the latest window changed it
        self._last = -1          # the latest window's stop (a boundary)
        self._started = False    # an exit speed has been fixed (a plan to follow exists)

    def add(self, j: int, corner: float, start: float, acceleration: float, jerk: float) -> None:
        """Span j comes into sight: the speed allowed at its start, where it starts (its length is known once
        the next span's start is) and its bounds."""
        self._span[j] = (corner, start, acceleration, jerk)

    def exit_speed(self, i: int, entry: float, corner: float, room: float, last: int, stop: float,
                   horizon: float) -> float:
        """Span i's exit speed, entered at ``entry``: at most ``corner`` (the speed allowed at boundary
        i + 1) and what span i reaches from its entry within its ``room`` (its whole length less the spare,
        though a span longer than the window is seen only in part), and one from which the spans up to
        boundary ``last`` can come to ``stop`` there (0: the window's end or the program's), span ``last`` - 1
        seen up to arc length ``horizon``. ValueError where span i cannot slow down to it and no earlier
        window's plan exists (a plan entered above its first span's feed)."""
        _, start, acc, jerk = self._span[i]
        forward = min(corner, reach(entry, room, max(corner, entry), acc, jerk))
        changed = self._backward(i, last, stop, horizon)
        v_next = min(forward, self._chain[i + 1])
        if entry > reach(v_next, room, max(entry, v_next), acc, jerk) * (1.0 + 1e-12):
            if not self._started:
                raise ValueError("the entry feed cannot be brought down to the look-ahead's speed within the "
                                 "first span")
            for j, value in changed.items():
                if value is not None:
                    self._kept.setdefault(j, value)
            v_next = min(forward, self._kept.get(i + 1, self._chain[i + 1]))
        else:
            self._kept.clear()
        self._started = True
        for table in (self._span, self._chain, self._kept):
            table.pop(i, None)
        return v_next

    def _room(self, j: int, last: int, horizon: float) -> float:
        """Span j's length as far as seen, less the spare."""
        end = horizon if j == last - 1 else self._span[j + 1][1]
        return (end - self._span[j][1]) * (1.0 - SPARE)

    def _backward(self, i: int, last: int, stop: float, horizon: float) -> dict:
        """The pass from the stop at boundary ``last`` back to boundary i + 1, into _chain; returns the
        boundaries it changed with their speeds before (None: none there)."""
        chain, spans = self._chain, self._span
        changed = {last: chain.get(last)}
        chain[last] = back = stop
        previous_last, self._last = self._last, last
        for j in range(last - 1, i, -1):
            corner, _, acc, jerk = spans[j]
            back = min(corner, reach(back, self._room(j, last, horizon), max(corner, back), acc, jerk))
            old = chain.get(j)
            if old == back and j < previous_last - 1:        # seen whole before too: the same from here back
                break
            changed[j] = old
            chain[j] = back
        return changed
