"""The nodes' console scripts (setup.py's ``console_scripts``: what ``ros2 run`` and the launch file start).

Each imports its node's module only when it runs, so that an import the user has to act on ends the process
with one line on stderr and exit status 1, never a traceback: an rclpy that lacks an internal the lean loops
use (:class:`~contouring_ros.errors.IncompatibleRclpy`, raised by the check that importing
:mod:`contouring_ros.rclpy_adapter` makes), or any other ContouringError (a plugin registry that cannot be
listed). Once imported, the node's ``main`` reports its own errors the same way
(:func:`contouring_ros.nodes.lockstep.run_node`). ``python -m contouring_ros.nodes.<node>``, as the runner
starts a node, runs the node's module itself; the runner then names the node with the last line it wrote.
"""
from __future__ import annotations

import contextlib
import sys

from ..errors import ContouringError

__all__ = ["interpolator", "plant", "servo", "contour_estimator", "ccc", "recorder"]


@contextlib.contextmanager
def _importing_the_node():
    """A ContouringError raised by importing a node's module: one line on stderr, exit status 1."""
    try:
        yield
    except ContouringError as error:
        print(f"error: {error}", file=sys.stderr)
        raise SystemExit(1) from None


def interpolator():
    with _importing_the_node():
        from .interpolator import main
    main()


def plant():
    with _importing_the_node():
        from .plant import main
    main()


def servo():
    with _importing_the_node():
        from .servo import main
    main()


def contour_estimator():
    with _importing_the_node():
        from .contour_estimator import main
    main()


def ccc():
    with _importing_the_node():
        from .ccc import main
    main()


def recorder():
    with _importing_the_node():
        from .recorder import main
    main()
