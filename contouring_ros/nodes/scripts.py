"""The nodes' console scripts (setup.py's ``console_scripts``: what ``ros2 run`` and the launch file start).

Each imports its node's module only when it runs, so that an import the user has to act on ends the process
with one line on stderr and exit status 1, never a traceback: an rclpy that lacks an internal the lean loops
use (:class:`~contouring_ros.errors.IncompatibleRclpy`, raised by the check that importing
:mod:`contouring_ros.nodes.rclpy_adapter` makes), or any other ContouringError (a plugin registry that cannot be
listed). Once imported, the node's ``main`` reports its own errors the same way
(:func:`contouring_ros.nodes.process.run_node`). ``python -m contouring_ros.nodes.<node>``, as the runner
starts a node, runs the node's module itself; the runner then names the node with the last line it wrote.
"""
from __future__ import annotations

import contextlib
import importlib
import sys

from ..errors import ContouringError
from ..wire import catalogue

__all__ = [node.console_script for node in catalogue.NODES]


@contextlib.contextmanager
def _importing_the_node():
    """A ContouringError raised by importing a node's module: one line on stderr, exit status 1."""
    try:
        yield
    except ContouringError as error:
        print(f"error: {error}", file=sys.stderr)
        raise SystemExit(1) from None


def _script(node: catalogue.Node):
    """The console script of ``node``: import its module (one line if that fails), then run its ``main``."""
    def script():
        with _importing_the_node():
            main = importlib.import_module(node.module).main
        return main()
    script.__name__ = script.__qualname__ = node.console_script
    script.__doc__ = f"ros2 run contouring_ros {node.console_script}: the {node.name} node."
    return script


for _node in catalogue.NODES:
    globals()[_node.console_script] = _script(_node)
