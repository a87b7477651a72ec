"""A node's process: the entry point every node's main() shares, and the exit codes of its interruptions.

:func:`run_node` creates the node, runs it to the end in its timing mode and turns every way out into an
exit code; :func:`track_signals` and :func:`interrupted_code` tell an interruption, and which, from an error
(the composed layout's process uses them too).
"""
from __future__ import annotations

import signal
import sys
import threading
import time

import rclpy
from rclpy.executors import ExternalShutdownException

from .explain import help_text, wants_help
from ..errors import ContouringError

__all__ = ["ReceivedSignals", "track_signals", "interrupted_code", "run_node"]


class ReceivedSignals(list):
    """The numbers of the SIGINT and SIGTERM that arrived, in order; its methods are their handlers."""

    def note(self, signum, frame):
        """SIGTERM's handler: note it (rclpy's own handler has shut the context down)."""
        self.append(signum)

    def interrupt(self, signum, frame):
        """SIGINT's handler: note it and raise KeyboardInterrupt."""
        self.append(signum)
        raise KeyboardInterrupt


def track_signals() -> ReceivedSignals:
    """A list that receives the number of each SIGINT and SIGTERM that arrives (the handlers are installed
    before rclpy.init: rclpy's own handlers shut the context down and then call these), so that the exit
    code can tell an interruption, and which, from an error. SIGINT still raises KeyboardInterrupt."""
    received = ReceivedSignals()
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, received.note)
        signal.signal(signal.SIGINT, received.interrupt)
    return received


def interrupted_code(error: BaseException, received: list) -> int | None:
    """143 (SIGTERM) or 130 (SIGINT) when ``error`` is how an interruption ended a node's process (whatever
    the interrupted call raised once rclpy's handler had shut the context down: KeyboardInterrupt,
    ExternalShutdownException, an RCLError of a publisher whose context is gone), else None."""
    if not received and not isinstance(error, ContouringError):
        time.sleep(0.01)          # a signal whose Python handler has not run yet runs now (sleep lets it in)
    if signal.SIGTERM in received:
        return 143
    if received or isinstance(error, (KeyboardInterrupt, ExternalShutdownException)):
        return 130
    if not isinstance(error, ContouringError) and not rclpy.ok():
        return 130                # the context is gone: a signal's handler shut it down
    return None


def run_node(node_class, args=None) -> int:
    """Entry point shared by every node's main(): init, spin to the end, clean shutdown.

    Returns the process exit code: 0 when the run completed, 1 on an error (reported in one line), 130 when
    interrupted by SIGINT and 143 by SIGTERM, in any state (waiting for the graph, stepping, finishing),
    without a traceback.
    """
    if wants_help(sys.argv if args is None else args):
        print(help_text(node_class.role))
        return 0
    received = track_signals()
    node = None
    code = 0
    try:
        rclpy.init(args=args)
        node = node_class(args)
        if node.experiment.timing == "realtime" and node.role != "recorder":
            node.spin_realtime()
        else:
            node.spin()
        node.finish()
    except BaseException as error:   # every way out becomes an exit code; only a bug keeps its traceback
        code = interrupted_code(error, received)
        if code is None and isinstance(error, ContouringError):
            print(f"error: {error}", file=sys.stderr)
            code = 1
        elif code is None:
            raise
    finally:
        try:
            if node is not None:
                node.destroy()
        except Exception:          # a node whose context a signal shut down: what matters (the bag) is closed
            if code == 0:
                raise
        rclpy.try_shutdown()
    return code
