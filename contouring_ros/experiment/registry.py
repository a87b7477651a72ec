"""One registry per role: type name -> the class or factory that builds it, its parameters, its constraints.

Roles: curve, schedule, plant, disturbance, servo, estimator, controller. The built-in types are the entries
of :mod:`contouring_ros.experiment.catalogue` (one module per role); other packages add types through Python entry points of the
group ``contouring_ros.<role>s`` (``contouring_ros.estimators``, ``contouring_ros.controllers`` ...). An
entry point names either an :class:`Entry` or a class; a class gives

- ``params``: {key: :class:`contouring_ros.experiment.schema.Param`} (the keys of its section besides the type name),
- optionally ``from_section(section, context)`` (a classmethod building it); without one, its constructor
  is called with the section's keys and, by name, what the context holds (``curve``, ``schedule``,
  ``sample_time``, ``axes``, ``n_axes``, ``experiment``, ``axis``, ``position``, ``velocity``,
  ``acceleration``),
- optionally ``check_section(section, axes)`` -> None or (key, message): a constraint on its own section,
- controllers: ``whole_command = True`` when it computes every axis' whole command (servos then 'direct'),
  ``needs_state = True`` when it uses the reference and the axis states (the CCC node then takes them),
  ``gains``: the keys the benchmark tunes (default: its float keys whose names start with 'k'),
  ``check_combination(estimator, controller, servos)`` -> None or (key, message); ``preview_steps`` as a
  servo's (below, ``axis`` None), its ``look_ahead`` given an array (preview, n axes);
  servos: ``direct = True`` when it passes the controller's output through; ``preview_steps(section,
  experiment, axis)`` -> how many steps of reference beyond the current one its law reads (its object's
  ``preview``, given through ``look_ahead``; default none);
  plants: ``varied``: the physical parameters the benchmark's robustness checks and mismatch draws vary,
  ``response(section, w)``: |position / command| at w rad/s (the tuning space's frequencies); controllers and
  servos: ``tuning_space(section, context)``: the benchmark's tuning space (contouring_ros.core.tuning_space).

Entry points are listed once per role (importlib.metadata) and each is imported when its type is first
looked up, so a plugin that fails to load stops only what names it, with one line naming the plugin.
Validation (experiment.validate), building (experiment.build), batches, the graph's nodes and replay all read these
registries; an unknown type is refused naming the known ones.
"""
from __future__ import annotations

import inspect
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from importlib import metadata
from typing import Callable

from ..errors import ConfigError, ContouringError, one_line
from .guard import guard

__all__ = ["Entry", "Role", "BuildContext", "ROLES", "entry_from_class", "section_arguments"]

#: the roles an experiment names a type for, in the order of an experiment file; each has one :class:`Role`
#: (contouring_ros.experiment.catalogue.ROLES)
ROLES = ("curve", "schedule", "plant", "disturbance", "servo", "estimator", "controller")


@dataclass(frozen=True)
class Entry:
    """One type of a role."""

    name: str
    params: dict                          # key -> Param: the section's keys besides the type name
    build: Callable                       # build(section, context) -> the core object
    check: Callable | None = None         # check(section, axes) -> None | (key, message)
    combination: Callable | None = None   # controllers: (estimator, controller, servos) -> None | (key, message)
    whole_command: bool = False           # controllers: computes every axis' whole command
    direct: bool = False                  # servos: passes the contour controller's output through
    preview: Callable | None = None       # servos, controllers: (section, experiment, axis or None) -> steps of
                                          # reference ahead it reads (its object's ``preview``, via look_ahead)
    needs_state: bool = False             # controllers: uses the reference and the axis states
    reads_estimate: bool = True           # controllers: reads the contour estimate (False: every estimator gives
                                          # the same run, and the benchmark pairs it with the scenario's own only)
    gains: tuple | None = None            # the keys the benchmark's tuning varies (None: the float keys named k*)
    varied: tuple = ()                    # plants: the physical parameters robustness and mismatch draws vary
    response: Callable | None = None      # plants: (section, w) -> |position / command| at w [rad/s]
    tuning: Callable | None = None        # controllers, servos: (section, TuningContext) -> the benchmark's
                                          # tuning space (contouring_ros.core.tuning_space.Space) or None
    origin: str = "contouring_ros"        # the package (or entry point) it comes from

    @property
    def builtin(self) -> bool:
        """Whether the type is the package's own (not a plugin's)."""
        return self.origin == "contouring_ros"


class BuildContext:
    """What a factory may need besides its section: the experiment, the curve, the schedule (built when
    first asked for), one axis' name and initial state."""

    #: build_schedule(experiment, curve) -> the schedule, for :attr:`schedule`: set by
    #: :mod:`contouring_ros.experiment.build` (imported with every catalogue user), which this module does not import
    schedule_builder: Callable | None = None

    def __init__(self, experiment=None, curve=None, axis=None, position=None, velocity=None, acceleration=None,
                 where: str = "", schedule=None):
        self.experiment, self.curve, self.axis, self.where = experiment, curve, axis, where
        self.position, self.velocity, self.acceleration = position, velocity, acceleration
        self._schedule = schedule

    @property
    def schedule(self):
        if self._schedule is None:
            self._schedule = BuildContext.schedule_builder(self.experiment, self.curve)
        return self._schedule

    @property
    def sample_time(self) -> float:
        return self.experiment.sample_time

    @property
    def axes(self) -> tuple:
        return self.experiment.axes

    @property
    def n_axes(self) -> int:
        return len(self.experiment.axes)

    def get(self, name: str):
        return getattr(self, name) if name in _CONTEXT_NAMES else None


def section_arguments(section: dict, type_key: str = "type") -> dict:
    """A validated section's keys besides its type name: the keyword arguments of a constructor."""
    return {key: value for key, value in section.items() if key != type_key}


_CONTEXT_NAMES = ("experiment", "curve", "schedule", "sample_time", "axes", "n_axes", "axis", "position",
                  "velocity", "acceleration")


def _constructor_factory(cls) -> Callable:
    """build(section, context) calling ``cls`` with the section's keys and, by name, the context's objects."""
    parameters = inspect.signature(cls).parameters

    def build(section, context):
        arguments = {}
        for name, parameter in parameters.items():
            if parameter.kind in (parameter.VAR_POSITIONAL, parameter.VAR_KEYWORD):
                continue
            if name in section and name != "type":
                arguments[name] = section[name]
            elif name in _CONTEXT_NAMES:
                arguments[name] = context.get(name)
        return cls(**arguments)
    return build


def entry_from_class(name: str, cls, origin: str = "") -> Entry:
    """The entry of a plugin class (see the module's docstring for what it may define)."""
    build = getattr(cls, "from_section", None) or _constructor_factory(cls)
    return Entry(name=name, params=dict(getattr(cls, "params", {}) or {}), build=build,
                 check=getattr(cls, "check_section", None), combination=getattr(cls, "check_combination", None),
                 whole_command=bool(getattr(cls, "whole_command", False)), direct=bool(getattr(cls, "direct", False)),
                 preview=getattr(cls, "preview_steps", None),
                 needs_state=bool(getattr(cls, "needs_state", False)), gains=getattr(cls, "gains", None),
                 reads_estimate=bool(getattr(cls, "reads_estimate", True)),
                 varied=tuple(getattr(cls, "varied", ()) or ()), response=getattr(cls, "response", None),
                 tuning=getattr(cls, "tuning_space", None), origin=origin or getattr(cls, "__module__", ""))


class Role(Mapping):
    """The registry of one role: a mapping type name -> its parameter spec (what validation reads), with
    :meth:`entry` giving the whole :class:`Entry`. Built-ins are registered with :meth:`register`; entry
    points of ``contouring_ros.<role>s`` are listed when a name is first looked up."""

    def __init__(self, role: str, type_key: str = "type", description: str = ""):
        if role not in ROLES:
            raise ValueError(f"unknown role {role!r} (expected one of: {', '.join(ROLES)})")
        self.role, self.type_key, self.group = role, type_key, f"contouring_ros.{role}s"
        self.description = description or f"{role} {type_key}"      # what the type key means (descriptors)
        self._entries: dict = {}
        self._pending: dict | None = None     # entry point name -> EntryPoint, not loaded yet
        self.on_register: Callable | None = None    # called with each plugin Entry as it loads (bounds)

    # --- registering ---------------------------------------------------------------------------------
    def register(self, name: str, params: dict, build: Callable, **traits) -> Entry:
        entry = Entry(name=name, params=params, build=build, **traits)
        self._entries[name] = entry
        return entry

    def add(self, entry: Entry) -> Entry:
        self._entries[entry.name] = entry
        return entry

    def registered(self) -> dict:
        """{name: Entry} of the types registered so far (no entry point is listed or loaded)."""
        return dict(self._entries)

    def builtin(self) -> dict:
        """{name: params} of the types registered so far (no entry point is listed or loaded)."""
        return {name: entry.params for name, entry in self._entries.items()}

    # --- plugins -------------------------------------------------------------------------------------
    def _discover(self) -> dict:
        if self._pending is None:
            pending = {}
            try:
                points = _entry_points().select(group=self.group)
            except Exception as error:     # a broken distribution's metadata
                raise ConfigError(f"cannot list the {self.group} plugins ({type(error).__name__}: "
                                  f"{one_line(error)})") from None
            for point in points:
                if point.name in self._entries or point.name in pending:
                    warnings.warn(f"plugin {point.name!r} ({self.group}: {point.value}) is named like a "
                                  f"{self.role} type already known; it is ignored", stacklevel=3)
                    continue
                pending[point.name] = point
            self._pending = pending
        return self._pending

    def _load(self, name: str) -> Entry:
        point = self._pending.pop(name)
        where = f"plugin {name!r} ({self.group}: {point.value})"
        try:
            target = point.load()
        except (Exception, SystemExit) as error:      # sys.exit() at import must not end the run with 0
            self._pending[name] = point       # the next lookup says so again
            raise ConfigError(f"{where} failed to load: {type(error).__name__}: {one_line(error)}") from None
        try:
            if isinstance(target, Entry):
                entry = Entry(**{**target.__dict__, "name": name, "origin": point.value})
            elif callable(target):
                entry = entry_from_class(name, target, point.value)
            else:
                raise TypeError(f"expected a class or a contouring_ros.experiment.registry.Entry, got {type(target).__name__}")
            if not isinstance(entry.params, dict):
                raise TypeError("params must be a mapping of key -> Param")
            if self.on_register is not None:
                self.on_register(entry)
        except Exception as error:
            self._pending[name] = point
            raise ConfigError(f"{where} failed to load: {type(error).__name__}: {one_line(error)}") from None
        self._entries[name] = entry
        return entry

    # --- lookup --------------------------------------------------------------------------------------
    def names(self) -> list:
        return list(self._entries) + [name for name in self._discover() if name not in self._entries]

    def entry(self, name: str) -> Entry:
        """The entry of ``name``; a ConfigError naming the known types if there is none."""
        if name in self._entries:
            return self._entries[name]
        if name in self._discover():
            return self._load(name)
        raise ConfigError(f"{self.role} {self.type_key} {name!r} is unknown (expected one of: "
                          f"{', '.join(self.names())})")

    def build(self, section: dict, context: BuildContext | None = None):
        """The core object of a validated ``section``. A plugin's object is built, and its methods run, under a
        guard (:mod:`contouring_ros.experiment.guard`): what it raises (SystemExit included) or returns that is not
        finite becomes one RunError line naming the plugin, the step or the argument, and what failed."""
        entry = self.entry(section[self.type_key])
        context = context if context is not None else BuildContext()
        if entry.builtin:
            return entry.build(section, context)
        where = f"plugin {entry.name!r} ({self.group}: {entry.origin})"
        try:
            built = entry.build(section, context)
        except (Exception, SystemExit) as error:
            if isinstance(error, ContouringError):
                raise
            raise ConfigError(f"{where} failed to build: {type(error).__name__}: {one_line(error)}") from None
        guard(built, where, self.role)
        return built

    def __getitem__(self, name):
        if not isinstance(name, str) or name not in self:
            raise KeyError(name)
        return self.entry(name).params

    def __contains__(self, name) -> bool:
        return isinstance(name, str) and (name in self._entries or name in self._discover())

    def __iter__(self):
        return iter(self.names())

    def __len__(self) -> int:
        return len(self.names())

    def __repr__(self) -> str:
        return f"<{self.role} registry: {', '.join(self._entries)}>"


_ALL_POINTS = None


def _entry_points():
    """Every installed entry point, listed once per process (a listing reads every distribution's
    metadata: about 0.2 s, so the seven roles share one)."""
    global _ALL_POINTS
    if _ALL_POINTS is None:
        _ALL_POINTS = metadata.entry_points()
    return _ALL_POINTS
