"""Old import paths of modules that moved into the role folders, kept working for code written against them.

``import contouring_ros.bag`` (or ``from contouring_ros import bag``) gives :mod:`contouring_ros.records.bag`
itself, with a DeprecationWarning that names the new path; nothing else is loaded until such a name is used.
"""
from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import warnings

#: old module -> where it lives now (all under contouring_ros)
MOVED = {
    "graph": "wire.graph", "cdr": "wire.cdr", "nodes.catalogue": "wire.catalogue",
    "registry": "experiment.registry", "guard": "experiment.guard",
    "rclpy_adapter": "nodes.rclpy_adapter", "parameters": "nodes.parameters",
    "runner": "run.runner", "composed": "run.composed", "playback": "run.playback",
    "bag": "records.bag", "scoring": "records.scoring", "blocks": "records.blocks", "export": "records.export",
    "outputs": "records.outputs", "analysis": "records.analysis",
    "sweep": "studies.sweep", "learning": "studies.learning", "tuning": "studies.tuning",
    "search": "studies.search", "benchmark": "studies.benchmark", "claims": "studies.claims",
    "paper": "studies.paper", "readings": "studies.readings", "parts": "studies.parts",
    "checkpoints": "studies.checkpoints", "executors": "studies.executors",
}
PACKAGE = __name__.rpartition(".")[0]


class MovedFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds an old module name and loads it as the module at its new path (the same module object)."""

    def find_spec(self, fullname, path=None, target=None):
        old = fullname[len(PACKAGE) + 1:] if fullname.startswith(PACKAGE + ".") else None
        if old not in MOVED:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        new = f"{PACKAGE}.{MOVED[spec.name[len(PACKAGE) + 1:]]}"
        warnings.warn(f"{spec.name} has moved to {new}", DeprecationWarning, stacklevel=2)
        return importlib.import_module(new)

    def exec_module(self, module):
        """The module at the new path is already executed."""


def install() -> None:
    """Put the finder on ``sys.meta_path`` once."""
    if not any(isinstance(finder, MovedFinder) for finder in sys.meta_path):
        sys.meta_path.append(MovedFinder())
