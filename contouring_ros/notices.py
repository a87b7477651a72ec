"""Notes on stderr for a person waiting: what is still under way while a long step runs."""
from __future__ import annotations

import sys
import threading
import time

__all__ = ["note_while_slow", "progress_of", "SLOW_NOTE_AFTER", "SLOW_NOTE_EVERY", "PROGRESS_LINE_EVERY"]

SLOW_NOTE_AFTER, SLOW_NOTE_EVERY = 3.0, 15.0     # s before the first note on stderr, then between notes
PROGRESS_LINE_EVERY = 10.0     # s between two progress lines off a terminal


class note_while_slow:
    """Context manager: while its block runs longer than SLOW_NOTE_AFTER seconds, a line on stderr every
    SLOW_NOTE_EVERY seconds says ``what`` is still under way (on a terminal or not: a log shows it too)."""

    def __init__(self, what: str):
        self.what = what

    def __enter__(self):
        self.done, started = threading.Event(), time.monotonic()

        def watch():
            wait = SLOW_NOTE_AFTER
            while not self.done.wait(wait):
                print(f"note: {self.what}: still under way after {time.monotonic() - started:.0f} s",
                      file=sys.stderr, flush=True)
                wait = SLOW_NOTE_EVERY
        threading.Thread(target=watch, daemon=True).start()
        return self

    def __exit__(self, *exc):
        self.done.set()
        return False


class progress_of:
    """Context manager for the progress of a long command: called with the amount done so far (out of
    ``total`` ``unit``s), it shows a progress bar on stderr where stderr is a terminal (``terminal``: decide
    otherwise), and off one (a log, a pipe) a line every PROGRESS_LINE_EVERY seconds: ``run: 3200 of 9694
    steps (33%) after 12 s``, the first as soon as the amount moves, so a log says the command is alive.
    ``waiting``: what the line says while nothing is done yet."""

    def __init__(self, total: float, what: str, unit: str = "step", terminal: bool | None = None,
                 waiting: str = "starting"):
        self.total, self.what, self.unit, self.waiting = total, what, unit, waiting
        self.terminal = sys.stderr.isatty() if terminal is None else terminal
        self.bar, self.done = None, 0

    def __enter__(self):
        self.started = time.monotonic()
        self.next_line = self.started + SLOW_NOTE_AFTER
        if self.terminal:
            from tqdm import tqdm
            self.bar = tqdm(total=self.total, desc=self.what, unit=self.unit, leave=False, mininterval=0.2,
                            dynamic_ncols=True)
        return self

    def __call__(self, done) -> None:
        done = min(done, self.total)
        if self.bar is not None:
            if done > self.done:
                self.bar.update(done - self.done)
        elif time.monotonic() >= self.next_line:
            self.next_line = time.monotonic() + PROGRESS_LINE_EVERY
            print(self.line(done), file=sys.stderr, flush=True)
        self.done = max(self.done, done)

    def line(self, done) -> str:
        """The line shown off a terminal for ``done`` of the total."""
        elapsed = time.monotonic() - self.started
        if not done:
            return f"{self.what}: {self.waiting} ({elapsed:.0f} s)"
        share = 100.0 * done / self.total if self.total else 100.0
        return f"{self.what}: {done:g} of {self.total:g} {self.unit}s ({share:.0f}%) after {elapsed:.0f} s"

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()
        return False
