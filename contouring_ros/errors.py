"""Errors that reach the user as one line."""
from __future__ import annotations

__all__ = ["ContouringError", "ConfigError", "RunError", "Interrupted", "BagError", "ScoreError", "Diverged",
           "OutputError", "IncompatibleRclpy", "one_line"]


def one_line(error) -> str:
    """An exception's message on one line, at most 300 characters (what a plugin raised, for our messages)."""
    return " ".join(str(error).split())[:300] or "(no message)"


class ContouringError(Exception):
    """Base class: the message is a complete one-line explanation for the user."""


class ConfigError(ContouringError):
    """An experiment file is malformed; the message names the file, the key and what was expected."""


class RunError(ContouringError):
    """The node graph failed (a node died, stalled or timed out); the message names the node.

    ``bag`` is the path of the bag the run was writing, if it got that far.
    """

    def __init__(self, message: str, bag=None):
        super().__init__(message)
        self.bag = bag


class Interrupted(RunError):
    """SIGINT or SIGTERM stopped a run; the message says what exists (the bag, or no bag yet). ``code`` is
    the exit status the command ends with: 130 for SIGINT, 143 for SIGTERM."""

    def __init__(self, message: str, bag=None, code: int = 130):
        super().__init__(message, bag)
        self.code = code


class BagError(ContouringError):
    """A bag cannot be read or lacks what scoring needs."""


class OutputError(ContouringError):
    """A file cannot be written (a full disk, a folder one cannot write into, a file where a folder is
    expected); the message names the path. Nothing half-written is left under the file's name."""


class IncompatibleRclpy(ContouringError, ImportError):
    """The installed rclpy lacks an internal the lean loops use: raised by importing
    :mod:`contouring_ros.nodes.rclpy_adapter` (an ImportError, as a failed import is), naming the rclpy found and the
    one the adapter was written for."""


class ScoreError(ContouringError):
    """A run cannot be scored as asked (e.g. no sample after the steady-state start time)."""


class Diverged(ContouringError, ArithmeticError):
    """A run's state left every plausible bound: ``diverged at t = ... s (step k): <what>``.

    ``step`` is the first step whose state is out of bounds; ``result`` holds the steps before it (a
    SimulationResult cut there) where the run that raised it kept them.
    """

    def __init__(self, message: str, step: int = 0, time: float = 0.0, result=None):
        super().__init__(message)
        self.step, self.time, self.result = step, time, result
