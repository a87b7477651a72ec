"""Building the core objects of a validated :class:`~.model.Experiment`: its curve, schedule, plants,
servos, estimator, controller and in-position clock, each through its role's registry
(:mod:`.catalogue`), and the whole :class:`~contouring_ros.core.simulation.ControlLoop`."""
from __future__ import annotations

import json
import threading
from collections import OrderedDict

import numpy as np

from ..core import curves
from ..core.interpolation import InPositionClock, ReferenceTable, reference
from ..core.feed_control import FeedControl, parse_feed_events
from ..core.monitoring import Monitor
from ..core.simulation import ControlLoop
from ..errors import ConfigError
from ..wire.graph import LOOKAHEAD
from .registry import BuildContext
from .catalogue import CONTROLLERS, CURVES, ESTIMATORS, PLANTS, SCHEDULES, SERVOS
from .catalogue.curves import TOOL_PATH_TYPES
from .catalogue.disturbances import build_disturbance
from .model import Experiment

__all__ = ["build_curve_from", "build_curve", "build_schedule_from", "build_schedule", "build_disturbance",
           "initial_state", "build_plant", "in_position_windows", "planned_tool_path", "monitoring_limits",
           "interpolator_takes_state", "build_monitor", "build_feed_control", "build_clock", "build_servo", "build_estimator",
           "build_controller", "build_loop", "build_path", "shares_path", "schedule_duration", "servo_preview",
           "controller_preview", "reference_preview"]

#: how many paths (curve, schedule, sample time) :func:`build_path` keeps
KEPT_PATHS = 8
_paths = OrderedDict()
_durations = OrderedDict()
_paths_lock = threading.Lock()


def build_curve_from(section: dict, where: str = "curve") -> curves.Curve:
    try:
        curve = CURVES.build(section, BuildContext(where=where))
    except ValueError as error:
        raise ConfigError(f"{where}: curve: {error}") from None
    if "contour_error_window" in section:       # a key of every built-in curve; a plugin's curve keeps its own
        curve.contour_error_window = section["contour_error_window"]
    return curve


def build_curve(experiment: Experiment) -> curves.Curve:
    return build_curve_from(experiment.curve, experiment.path)


def build_schedule_from(section: dict, curve, where: str = "schedule"):
    return SCHEDULES.build(section, BuildContext(curve=curve, where=where))


def build_schedule(experiment: Experiment, curve=None):
    return build_schedule_from(experiment.schedule, curve or build_curve(experiment), experiment.path)


BuildContext.schedule_builder = build_schedule


def initial_state(experiment: Experiment, curve=None, schedule=None):
    """Initial axis positions, velocities and accelerations: on the reference at t = 0, moving with it
    (``on_reference``) or at rest (``at_rest``)."""
    curve = curve or build_curve(experiment)
    schedule = schedule or build_schedule(experiment, curve)
    start = reference(curve, schedule, 0.0)
    if experiment.initial_state == "on_reference":
        return start.position, start.velocity, start.acceleration
    return start.position, np.zeros_like(start.velocity), np.zeros_like(start.acceleration)


def build_plant(experiment: Experiment, axis: str, position: float, velocity: float):
    return PLANTS.build(experiment.plants[axis], BuildContext(experiment, axis=axis, position=position,
                                                              velocity=velocity, where=experiment.path))


def _getter(shared):
    return shared.get if isinstance(shared, dict) else lambda key: getattr(shared, key)


def planned_tool_path(shared) -> bool:
    """Whether the experiment (an Experiment or the shared section) runs a tool path planned by the
    jerk-limited feed plan: a gcode curve, or a toolpath with a feedrate schedule with jerk."""
    get = _getter(shared)
    curve, schedule = get("curve"), get("schedule")
    return curve["type"] == "gcode" or bool(curve["type"] == "toolpath" and schedule["type"] == "feedrate"
                                            and schedule.get("jerk"))


def monitoring_limits(shared) -> tuple | None:
    """(contour limit, per-axis following limits) [m] of the shared keys ``contour_error_limit`` and
    ``following_error_limit`` where either is on (validation allows them on planned tool paths only); else None."""
    get = _getter(shared)
    contour, following = float(get("contour_error_limit")), [float(v) for v in get("following_error_limit")]
    if not contour and not any(following):
        return None
    return contour, following * len(get("axes")) if len(following) == 1 else following


def interpolator_takes_state(shared) -> bool:
    """Whether the interpolator subscribes to every axis state: for the in-position check at exact stops or
    for following-error monitoring (decided from the shared keys alone, so every node agrees)."""
    limits = monitoring_limits(shared)
    return in_position_windows(shared) is not None or (limits is not None and any(limits[1]))


def build_monitor(experiment: Experiment):
    """The run's :class:`~contouring_ros.core.monitoring.Monitor`, or None without limits."""
    limits = monitoring_limits(experiment)
    if limits is None:
        return None
    if reference_preview(experiment):
        raise ConfigError(f"{experiment.path}: contour_error_limit / following_error_limit: monitoring does not "
                          "run with a servo or controller that reads the reference ahead (its preview would not "
                          "follow the stop)")
    return Monitor(limits[0], limits[1], LOOKAHEAD)


def build_feed_control(experiment: Experiment, curve, schedule, clock, monitor, live: bool = False):
    """The run's :class:`~contouring_ros.core.feed_control.FeedControl` where it has feed events or a
    monitor, or takes them while it runs (``live``: the realtime interpolator's hold, resume and override
    interfaces, on a planned tool path whose reference no servo reads ahead); else None (the reference comes
    from the plan and the in-position clock alone)."""
    events = parse_feed_events(experiment.feed_events, experiment.sample_time)
    live = live and planned_tool_path(experiment) and not reference_preview(experiment)
    if not events and monitor is None and not live:
        return None
    if events and reference_preview(experiment):
        raise ConfigError(f"{experiment.path}: feed_events: holds and overrides do not run with a servo or controller "
                          "that reads the reference ahead (its preview would not follow the new plan)")
    windows = in_position_windows(experiment)

    def clock_for(plan):
        return InPositionClock(plan, curve, windows, experiment.sample_time,
                               experiment.schedule["in_position_timeout"], LOOKAHEAD)
    return FeedControl(curve, schedule, experiment.sample_time, clock, clock_for, monitor, events, LOOKAHEAD)


def in_position_windows(shared) -> list | None:
    """Each axis' in-position window [m] (the shared key ``in_position``, an Experiment or the shared
    section) where the reference waits at exact stops for the axes: a tool path planned by the jerk-limited
    feed plan with a window > 0; else None (the reference runs on the plan's own time and the interpolator
    takes no axis state)."""
    get = _getter(shared)
    windows = [float(w) for w in get("in_position")]
    if not planned_tool_path(shared) or not any(windows):
        return None
    return windows * len(get("axes")) if len(windows) == 1 else windows


def build_clock(experiment: Experiment, curve, schedule):
    """The reference's :class:`~contouring_ros.core.interpolation.InPositionClock`, or None (see
    :func:`in_position_windows`)."""
    windows = in_position_windows(experiment)
    if windows is None or not hasattr(schedule, "stops"):
        return None
    return InPositionClock(schedule, curve, windows, experiment.sample_time,
                           experiment.schedule["in_position_timeout"], LOOKAHEAD)


def servo_preview(experiment: Experiment, axis: str) -> int:
    """How many steps of reference beyond the current one the axis' servo law reads (its catalogue entry's
    ``preview``; 0 for most laws)."""
    return _reads_ahead(SERVOS, experiment.servos[axis], experiment, axis)


def reference_preview(experiment: Experiment) -> int:
    """How many steps of reference beyond the current one the interpolator publishes with each: the shared key
    ``reference_preview``, or the most any servo of the experiment reads where that is more (contouring-ros
    run sets the key so; docs/ARCHITECTURE.md, "Reference preview")."""
    return max([experiment.reference_preview, controller_preview(experiment)]
               + [servo_preview(experiment, axis) for axis in experiment.servos])


def controller_preview(experiment: Experiment) -> int:
    """How many steps of reference beyond the current one the contour controller reads (its catalogue entry's
    ``preview``; 0 for most, and for an experiment without a controller section)."""
    return _reads_ahead(CONTROLLERS, experiment.controller, experiment, None) if experiment.controller else 0


def _reads_ahead(role, section: dict, experiment: Experiment, axis) -> int:
    """The ``preview`` of the catalogue entry of ``section``'s type in ``role`` (0 where it states none)."""
    entry = role.entry(section[role.type_key])
    return int(entry.preview(section, experiment, axis)) if entry.preview is not None else 0


def _check_preview(built, wanted: int, where: str) -> None:
    """Refuse a built object whose ``preview`` (what the loop gives it) differs from its catalogue entry's
    (what the interpolator publishes, decided before anything is built); ``where`` names the type."""
    has = int(getattr(built, "preview", 0) or 0)
    if has != wanted:
        raise ConfigError(f"{where}'s object has preview = {has} but its registry entry gives {wanted}: give the "
                          "Entry preview as its object has it")


def build_servo(experiment: Experiment, axis: str, position: float, velocity: float, acceleration: float):
    """The axis' servo law. Its object's ``preview`` (what the loop gives it) must be its catalogue entry's
    (what the interpolator publishes, before anything is built)."""
    servo = SERVOS.build(experiment.servos[axis], BuildContext(experiment, axis=axis, position=position,
                                                               velocity=velocity, acceleration=acceleration,
                                                               where=experiment.path))
    _check_preview(servo, servo_preview(experiment, axis),
                   f"{experiment.path}: /{axis}/servo.law: the {experiment.servos[axis]['law']} law")
    return servo


def build_estimator(experiment: Experiment, curve, schedule=None):
    """The contour-error estimator (``schedule``: the path's, where the caller has it; else built if asked for)."""
    return ESTIMATORS.build(experiment.estimator, BuildContext(experiment, curve, where=experiment.path,
                                                               schedule=schedule))


def build_controller(experiment: Experiment, curve, schedule=None):
    """The contour controller (``schedule``: as :func:`build_estimator`). Its object's ``needs_state`` (what
    the simulation reads) must be its catalogue entry's (what the runner and the CCC node read, before
    anything is built)."""
    controller = CONTROLLERS.build(experiment.controller, BuildContext(experiment, curve, where=experiment.path,
                                                                       schedule=schedule))
    entry = CONTROLLERS.entry(experiment.controller["type"])
    if bool(getattr(controller, "needs_state", False)) != entry.needs_state:
        raise ConfigError(f"{experiment.path}: /ccc.type: the {entry.name} controller's object has needs_state = "
                          f"{bool(getattr(controller, 'needs_state', False))} but its registry entry has "
                          f"{entry.needs_state} ({entry.origin}): give the Entry needs_state as its object has it")
    _check_preview(controller, controller_preview(experiment), f"{experiment.path}: /ccc.type: the {entry.name} controller")
    return controller


def build_path(experiment: Experiment) -> tuple:
    """(curve, schedule, :class:`~contouring_ros.core.interpolation.ReferenceTable` or None) of the experiment.

    Runs along the same path (the same curve and schedule sections and sample time: a sweep's or a
    tuning's runs, which vary gains and plants) share one curve, one schedule and one table of the
    reference at each step, built once: a feedrate schedule's profile and every step's reference are the
    same for all of them. The last :data:`KEPT_PATHS` paths are kept. Built afresh, with no table: part
    programs (read from files; exact stops make each run's reference times its own) and curves or
    schedules of plugins (whose objects may keep state)."""
    if not shares_path(experiment.curve, experiment.schedule):
        curve = build_curve(experiment)
        return curve, build_schedule(experiment, curve), None
    key = json.dumps([experiment.curve, experiment.schedule, experiment.sample_time], sort_keys=True, default=repr)
    with _paths_lock:
        path = _paths.get(key)
        if path is not None:
            _paths.move_to_end(key)
            return path
    curve = build_curve(experiment)
    schedule = build_schedule(experiment, curve)
    path = (curve, schedule, ReferenceTable(curve, schedule, experiment.sample_time))
    with _paths_lock:
        path = _paths.setdefault(key, path)
        while len(_paths) > KEPT_PATHS:
            _paths.popitem(last=False)
    return path


def shares_path(curve_section: dict, schedule_section: dict) -> bool:
    """Whether runs along this curve and schedule share their objects (:func:`build_path`): built-in types,
    not a tool path."""
    curve_type, schedule_type = curve_section["type"], schedule_section["type"]
    return curve_type not in TOOL_PATH_TYPES and CURVES.entry(curve_type).builtin and \
        SCHEDULES.entry(schedule_type).builtin


def schedule_duration(curve_section: dict, schedule_section: dict, curve, where: str) -> tuple:
    """(duration [s], exact stops) of the schedule ``schedule_section`` builds along ``curve``
    (:func:`build_schedule_from`). Kept for the last :data:`KEPT_PATHS` paths that :func:`build_path` would
    share: a tuning validates the same path's experiment for every point it tries, and a feedrate
    schedule's profile is a pass over 20001 points."""
    def built() -> tuple:
        schedule = build_schedule_from(schedule_section, curve, where)
        return schedule.duration, len(getattr(schedule, "stops", ()))

    if not shares_path(curve_section, schedule_section):
        return built()
    key = json.dumps([curve_section, schedule_section], sort_keys=True, default=repr)
    with _paths_lock:
        found = _durations.get(key)
    if found is None:
        found = built()
        with _paths_lock:
            _durations[key] = found
            while len(_durations) > KEPT_PATHS:
                _durations.popitem(last=False)
    return found


def build_loop(experiment: Experiment) -> ControlLoop:
    """Every core object of the experiment, in their initial state (the curve, schedule and reference table
    shared with earlier runs along the same path: :func:`build_path`)."""
    curve, schedule, table = build_path(experiment)
    positions, velocities, accelerations = initial_state(experiment, curve, schedule)
    axes = experiment.axes
    clock, monitor = build_clock(experiment, curve, schedule), build_monitor(experiment)
    return ControlLoop(
        curve=curve, schedule=schedule, clock=clock,
        plants=[build_plant(experiment, a, positions[i], velocities[i]) for i, a in enumerate(axes)],
        servos=[build_servo(experiment, a, positions[i], velocities[i], accelerations[i])
                for i, a in enumerate(axes)],
        estimator=build_estimator(experiment, curve, schedule),
        controller=build_controller(experiment, curve, schedule),
        sample_time=experiment.sample_time, n_steps=experiment.n_steps,
        divergence_factor=experiment.divergence_factor, preview=reference_preview(experiment),
        reference_table=table, monitor=monitor,
        feed_control=build_feed_control(experiment, curve, schedule, clock, monitor))
