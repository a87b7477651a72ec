"""The guard a plugin's object runs under: what its methods raise, or return that is not finite, becomes one line.

A type from another package (an entry point of :mod:`contouring_ros.experiment.registry`) is code this package did not
write. Its object is given a subclass of its own class (same name, same attributes and results) whose
methods that the simulation and the nodes call, per role (:data:`GUARDED_METHODS`), turn

- an exception, ``SystemExit`` included (``sys.exit()`` in a plugin must not end a run with status 0), into
  a :class:`~contouring_ros.errors.RunError` naming the plugin, the method and the step or the argument;
- an output that is not a finite number (an infinite theta, a NaN command, a NaN curve point or plant
  state) into a :class:`PluginNotFinite`, a RunError that is also an ArithmeticError: a sweep or a tuning
  run records it as that combination's divergence, as it does a built-in's, instead of stopping every run.

``os._exit()`` ends the process without unwinding and cannot be caught in-process: in the node graph the
runner names the node that exited before completing its steps.
"""
from __future__ import annotations

import numpy as np

from ..errors import ContouringError, RunError, one_line

__all__ = ["GUARDED_METHODS", "PluginNotFinite", "guard"]

#: per role, the methods of a plugin's object that run during a simulation (the others are left as they are)
GUARDED_METHODS = {
    "curve": ("columns", "point", "derivatives"),
    "schedule": ("__call__",),
    "plant": ("step", "measure"),
    "disturbance": ("__call__",),
    "servo": ("step",),
    "estimator": ("step", "step_batch"),
    "controller": ("step",),
}
#: methods called once per control step: their messages name the step (counted per object)
STEP_METHODS = ("step", "step_batch")


class PluginNotFinite(RunError, ArithmeticError):
    """A plugin's method returned a value that is not a finite number."""


_GUARDED: dict = {}      # (plugin class, where, role) -> its guarded subclass


def guard(built, where: str, role: str) -> None:
    """Give ``built`` a subclass of its class whose :data:`GUARDED_METHODS` of ``role`` are checked (see the
    module). Copies of it stay guarded; an object whose class cannot be changed is left as it is."""
    cls = type(built)
    methods = [name for name in GUARDED_METHODS.get(role, ()) if callable(getattr(cls, name, None))]
    if not methods:
        return
    guarded = _GUARDED.get((cls, where, role))
    if guarded is None:
        body = {"__slots__": (), "__module__": cls.__module__, "__qualname__": cls.__qualname__}
        body.update({name: _checked(getattr(cls, name), name, where) for name in methods})
        guarded = _GUARDED[(cls, where, role)] = type(cls.__name__, (cls,), body)
    try:
        built.__class__ = guarded
    except TypeError:
        pass


def _checked(method, name: str, where: str):
    def checked(self, *args, **kwargs):
        k = None
        if name in STEP_METHODS:
            state = getattr(self, "__dict__", None)
            k = state.get("_plugin_steps", 0) if state is not None else 0
            if state is not None:
                state["_plugin_steps"] = k + 1

        def at() -> str:              # only on failure: formatting the arguments costs more than the call
            return f"at step {k}" if k is not None else f"in {name}({_brief(args)})"
        try:
            out = method(self, *args, **kwargs)
        except (Exception, SystemExit) as error:
            if isinstance(error, ContouringError):
                raise
            raise RunError(f"{where} failed {at()}: {type(error).__name__}: {one_line(error)}") from None
        if out is None:                       # a plant's step: its state is checked by measure()
            return out
        if hasattr(out, "theta") and hasattr(out, "vector"):          # a contour estimate
            parts = (("theta", out.theta), ("vector", out.vector), ("signed", getattr(out, "signed", 0.0)))
        else:
            parts = (("value", out),)
        for part, value in parts:
            if not all_finite(value):
                raise PluginNotFinite(f"{where} returned a {part} that is not a finite number {at()} "
                                      f"({_shown(value)})")
        return out

    checked.__name__ = checked.__qualname__ = name
    checked.__doc__ = method.__doc__
    return checked


def all_finite(value) -> bool:
    """Whether every number in ``value`` (a number, an array, or nested sequences of them, ragged or not) is
    finite; False for anything that is not numbers."""
    try:
        return bool(np.all(np.isfinite(np.asarray(value, dtype=float))))
    except (TypeError, ValueError):
        if isinstance(value, (list, tuple)):
            return all(all_finite(item) for item in value)
        return False


def _shown(value, width: int = 80) -> str:
    """A value on one line, numbers as numpy prints them (no ``np.float64(...)`` wrappers)."""
    try:
        text = np.array2string(np.asarray(value, dtype=float), threshold=8)
    except (TypeError, ValueError):
        text = str(value)
    return " ".join(text.split())[:width]


def _brief(args) -> str:
    return ", ".join(_shown(a, 40) for a in args)
