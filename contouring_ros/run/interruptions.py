"""SIGINT and SIGTERM during a run of the graph, noted by the handler and raised where the runner checks.

An exception raised in the handler itself (Python's own SIGINT handler raises KeyboardInterrupt there) is lost,
with a traceback on stderr, where the signal lands in code whose exceptions Python ignores (an at-fork callback
while a node is started, such as logging's lock release, or a finaliser), and the run went on to exit 0. So the
handler only notes the signal, and the runner raises :class:`Terminated` where it checks
(:func:`raise_pending_termination`: after starting each node, at every poll of the nodes, 20 times a second).
"""
from __future__ import annotations

import signal

__all__ = ["Terminated", "TERMINATIONS", "note_interruptions", "raise_pending_termination", "restore_signals"]


class Terminated(Exception):
    """SIGINT or SIGTERM reached the runner while it started or watched the nodes."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


#: SIGINTs and SIGTERMs received during the current run, in the order they came
TERMINATIONS: list = []


def _note_termination(signum, frame):
    TERMINATIONS.append(signum)


def raise_pending_termination() -> None:
    """Raise :class:`Terminated` for the first signal noted, if any."""
    if TERMINATIONS:
        raise Terminated(TERMINATIONS[0])


def note_interruptions() -> dict:
    """Install :func:`_note_termination` for SIGTERM, and for SIGINT unless SIGINT is ignored (a runner
    started in the background by a shell without job control keeps ignoring Ctrl-C meant for the
    foreground); return the handlers it replaced."""
    TERMINATIONS.clear()
    replaced = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(sig) is not signal.SIG_IGN:
            replaced[sig] = signal.signal(sig, _note_termination)
    return replaced


def restore_signals(replaced: dict) -> list:
    """Put back the handlers :func:`note_interruptions` ``replaced``; return the signals noted and not yet
    answered, forgotten here."""
    for sig, handler in replaced.items():
        signal.signal(sig, handler)
    late = list(TERMINATIONS)
    TERMINATIONS.clear()
    return late
