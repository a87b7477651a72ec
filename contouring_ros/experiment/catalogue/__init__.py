"""The catalogue: every built-in type of every role, one module per role. Each type is a
:class:`contouring_ros.experiment.registry.Entry` holding together its keys (each a :class:`~..schema.Param` with its
default, check, range and meaning), its factory, its checks and its traits (the gains the benchmark tunes, a
plant's varied parameters, whether a controller needs the states). Plugins add entries of the same shape
through the entry point groups ``contouring_ros.<role>s`` (contouring_ros/experiment/registry.py).

- :mod:`.curves`, :mod:`.schedules`: the shared section's ``curve`` and ``schedule``,
- :mod:`.disturbances`, :mod:`.plants`: each axis' ``/<axis>/plant``,
- :mod:`.servos`: each axis' ``/<axis>/servo``,
- :mod:`.estimators`: ``/contour_estimator``,
- :mod:`.controllers`: ``/ccc``,
- :mod:`.shared`: the keys every node shares (``/**``) and the optional nodes' keys.
"""
from __future__ import annotations

from .. import registry
from ..ros_yaml import _PARAMETER_NAME
from ..schema import Param
from .controllers import CONTROLLERS
from .curves import CURVES
from .disturbances import DISTURBANCES
from .estimators import ESTIMATORS
from .plants import PLANTS
from .schedules import SCHEDULES
from .servos import SERVOS
from .shared import GLOBALS, OPTIONAL_NODES

__all__ = ["CURVES", "SCHEDULES", "DISTURBANCES", "PLANTS", "SERVOS", "ESTIMATORS", "CONTROLLERS", "ROLES",
           "ROLE_TYPES", "GLOBALS", "OPTIONAL_NODES"]

_REGISTRIES = {role.role: role for role in (CURVES, SCHEDULES, DISTURBANCES, PLANTS, SERVOS, ESTIMATORS, CONTROLLERS)}
#: role name -> its registry, in the order of registry.ROLES (a role without a registry here fails at import)
ROLES = {name: _REGISTRIES[name] for name in registry.ROLES}
#: node section -> (key holding the type name, registry)
ROLE_TYPES = {"plant": ("model", PLANTS), "servo": ("law", SERVOS),
              "contour_estimator": ("type", ESTIMATORS), "ccc": ("type", CONTROLLERS)}


def _check_plugin_params(entry) -> None:
    """What each plugin type's parameters go through as it loads: every value a Param with a usable name.
    A number whose Param states no range of its own gets its kind's (DEFAULT_BOUNDS), never the range of a
    built-in key of the same name."""
    for key, spec in entry.params.items():
        if not isinstance(spec, Param):
            raise TypeError(f"params[{key!r}]: expected a contouring_ros.experiment.schema.Param, got {type(spec).__name__}")
        if not _PARAMETER_NAME.match(key) or key in ("type", "law", "model"):
            raise TypeError(f"params[{key!r}]: not a usable parameter name")


for _role in ROLES.values():
    _role.on_register = _check_plugin_params
