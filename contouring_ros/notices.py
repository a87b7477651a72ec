"""Notes on stderr for a person waiting: what is still under way while a long step runs."""
from __future__ import annotations

import sys
import threading
import time

__all__ = ["note_while_slow", "SLOW_NOTE_AFTER", "SLOW_NOTE_EVERY"]

SLOW_NOTE_AFTER, SLOW_NOTE_EVERY = 3.0, 15.0     # s before the first note on stderr, then between notes


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
