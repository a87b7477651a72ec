"""Old import paths of modules that moved into the role folders, kept working for code written against them.

``import contouring_ros.scoring`` (or ``from contouring_ros import scoring``) gives
:mod:`contouring_ros.records.scoring` itself, with a DeprecationWarning that names the new path; nothing else is
loaded until such a name is used. An old module whose names now live in several modules
(``contouring_ros.bag``, ``.analysis``, ``.tuning``, ``.benchmark``, ``.claims``) gives a module of its own that
holds the public names of those, with a DeprecationWarning that names them.
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
    "scoring": "records.scoring", "blocks": "records.blocks", "export": "records.export",
    "outputs": "records.outputs",
    "sweep": "studies.sweep", "learning": "studies.learning", "search": "studies.search",
    "paper": "studies.paper", "readings": "studies.readings", "parts": "studies.parts",
    "checkpoints": "studies.checkpoints", "executors": "studies.executors",
}
#: old module -> the modules its names live in now (all under contouring_ros)
SPLIT = {
    "analysis": ("records.comparison", "records.replay", "records.traces", "records.figures", "records.html_report"),
    "bag": ("records.bag", "records.bag_reader", "records.bag_writer"),
    "tuning": ("studies.tuning", "studies.machine", "studies.gains", "studies.outcomes", "studies.loops",
               "studies.space", "studies.objective", "studies.tuner", "studies.summaries"),
    "benchmark": ("studies.benchmark", "studies.benchmark_parts", "studies.benchmark_report",
                  "studies.benchmark_figures"),
    "claims": ("studies.claims_file", "studies.claims", "studies.claims_maps", "studies.claims_report"),
}
PACKAGE = __name__.rpartition(".")[0]


class MovedFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds an old module name and loads it as the module at its new path (the same module object), or, for a
    module that was split, as a module of its own holding the public names of the modules it was split into."""

    def find_spec(self, fullname, path=None, target=None):
        old = fullname[len(PACKAGE) + 1:] if fullname.startswith(PACKAGE + ".") else None
        if old not in MOVED and old not in SPLIT:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        old = spec.name[len(PACKAGE) + 1:]
        if old in SPLIT:
            new = ", ".join(f"{PACKAGE}.{part}" for part in SPLIT[old])
            warnings.warn(f"{spec.name} has been split into {new}", DeprecationWarning, stacklevel=2)
            return None             # a new module, given the names of its parts by exec_module
        new = f"{PACKAGE}.{MOVED[old]}"
        warnings.warn(f"{spec.name} has moved to {new}", DeprecationWarning, stacklevel=2)
        return importlib.import_module(new)

    def exec_module(self, module):
        """The module at the new path is already executed; the module of a split one gets its parts' names."""
        names = []
        for part in SPLIT.get(module.__name__[len(PACKAGE) + 1:], ()):
            new = importlib.import_module(f"{PACKAGE}.{part}")
            module.__dict__.update({name: getattr(new, name) for name in new.__all__})
            names += new.__all__
        if names:
            module.__all__ = names


def install() -> None:
    """Put the finder on ``sys.meta_path`` once."""
    if not any(isinstance(finder, MovedFinder) for finder in sys.meta_path):
        sys.meta_path.append(MovedFinder())
