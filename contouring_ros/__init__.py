"""contouring_ros: multi-axis contouring control of CNC feed drives as a ROS 2 graph of rclpy nodes.

The Python API (:mod:`contouring_ros.api`) is available at the top level: ``load_experiment``, ``simulate``,
``simulate_passes``, ``read_bag``, ``sweep_grid`` and ``Run``; it is imported on first use, so the nodes start without it.
"""

from ._version import __version__ as __version__
from ._moved import install as _install_moved

_install_moved()       # the modules that moved into the role folders answer to their old names too
_API = ("Run", "load_experiment", "simulate", "simulate_passes", "read_bag", "sweep_grid")
__all__ = list(_API)


def __getattr__(name):
    if name in _API:
        from . import api
        return getattr(api, name)
    raise AttributeError(f"module 'contouring_ros' has no attribute {name!r}")


def __dir__():
    """The API's names beside the module's own, for ``dir()`` and completion (before the API is imported)."""
    return sorted(set(globals()) | set(_API))
