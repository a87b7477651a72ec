"""Schedules (core/interpolation.py, core/feed_planning.py): the shared section's ``schedule`` mapping, how
the curve parameter advances in time."""
from __future__ import annotations

from ...core import curves
from ...core.feed_planning import LOOKAHEAD_BLOCKS, FeedPlan
from ...core.interpolation import FeedrateSchedule, UniformSchedule
from ...errors import ConfigError
from ...notices import note_while_slow
from ..registry import Entry, Role, section_arguments
from ..schema import MAX_DURATION, Param, _fail, _printable

__all__ = ["SCHEDULES"]

SCHEDULES = Role("schedule", description="schedule type")

_THETA_RANGE = (-1e6, 1e6)
_S = "[s]"
#: the keys of the jerk-limited feed plan of a tool path (core/feed_planning.py)
_PLAN_KEYS = ("rapid_feedrate", "axis_feedrate", "axis_acceleration", "axis_jerk", "contour_tolerance", "tracking_lag",
              "exact_stop_dwell", "feed_override", "in_position_timeout", "lookahead_blocks")


def _feedrate_schedule(section, context):
    """The feedrate schedule: with a ``jerk`` bound (always for a part program) the look-ahead, jerk-limited
    feed plan of a tool path (core/feed_planning.py); without, the acceleration-bounded profile."""
    arguments = section_arguments(section)
    where = context.where
    program = getattr(context.curve, "program", None)
    jerk = arguments.pop("jerk")
    plan = {key: arguments.pop(key) for key in _PLAN_KEYS}
    if jerk or program is not None:
        plan.pop("in_position_timeout")      # the reference's, not the plan's (build.build_clock)
        return _feed_plan(where, context.curve, program, jerk, arguments, plan)
    for key, value in plan.items():
        if value not in (None, 0.0) and (key, value) not in (("feed_override", 100.0), ("in_position_timeout", 0.5),
                                                             ("lookahead_blocks", LOOKAHEAD_BLOCKS)):
            _fail(where, f"schedule.{key}", "applies to the jerk-limited feed plan of a tool path: give jerk too")
    if arguments["feedrate"] is None:
        _fail(where, "schedule.feedrate", "missing required key")
    for key, default in (("theta_start", context.curve.domain[0]), ("theta_end", context.curve.domain[1])):
        if arguments[key] is None:
            arguments[key] = default
    try:
        return FeedrateSchedule(context.curve, **arguments)
    except ValueError as error:
        raise ConfigError(f"{context.where}: schedule: {error}") from None


def _feed_plan(where, curve, program, jerk, arguments, plan):
    if not isinstance(curve, curves.ToolPath):
        _fail(where, "schedule.jerk", "the jerk-limited feed plan runs along a tool path (curve type toolpath or "
                                      "gcode)")
    if not jerk:
        _fail(where, "schedule.jerk", "missing required key (a part program is planned with a jerk bound)")
    for key in ("theta_start", "theta_end"):
        if arguments[key] is not None:
            _fail(where, f"schedule.{key}", "the feed plan covers the whole tool path: leave it out")
    if program is not None and program.has_feed_words and arguments["feedrate"] is not None:
        _fail(where, "schedule.feedrate", "the part program sets its feeds with F words: leave feedrate out")
    for key in ("axis_feedrate", "axis_acceleration", "axis_jerk", "tracking_lag"):
        if plan[key] is not None and len(plan[key]) not in (1, curve.dimension):
            _fail(where, f"schedule.{key}", f"expected 1 value or one per axis ({curve.dimension}), got "
                                            f"{len(plan[key])}")
    if plan["contour_tolerance"] and plan["tracking_lag"] is None:
        _fail(where, "schedule.tracking_lag", "missing required key (the contour-tolerance planner predicts the "
                                              "contour error from each axis' lag)")
    if plan["tracking_lag"] is not None and not plan["contour_tolerance"]:
        _fail(where, "schedule.tracking_lag", "used only with a contour_tolerance")
    try:
        with note_while_slow(f"{_printable(where)}: planning the feed along the tool path (a small jerk or "
                             "contour_tolerance plans many steps)"):
            return FeedPlan(curve, arguments["acceleration"], jerk, arguments["feedrate"], plan["rapid_feedrate"] or None,
                            arguments["normal_acceleration"], plan["axis_feedrate"], plan["axis_acceleration"],
                            plan["axis_jerk"], plan["contour_tolerance"], plan["tracking_lag"],
                            plan["exact_stop_dwell"], plan["feed_override"] / 100.0, plan["lookahead_blocks"])
    except ValueError as error:
        raise ConfigError(f"{_printable(where)}: schedule: {_printable(error, 400)}") from None


SCHEDULES.add(Entry("uniform", {
    "theta_start": Param("float", help="curve parameter at t = 0", bounds=_THETA_RANGE),
    "theta_end": Param("float", help="curve parameter at the end", bounds=_THETA_RANGE),
    "duration": Param("float", check="positive", help=f"time from theta_start to theta_end {_S}",
                      bounds=(1e-6, MAX_DURATION)),
}, lambda s, c: UniformSchedule(**section_arguments(s))))
SCHEDULES.add(Entry("feedrate", {
    # default: the curve's domain
    "theta_start": Param("float", None, help="curve parameter at t = 0", bounds=_THETA_RANGE),
    "theta_end": Param("float", None, help="curve parameter at the end", bounds=_THETA_RANGE),
    # default: none (a part program's F words give it)
    "feedrate": Param("float", None, "positive", help="commanded feedrate [m/s]", bounds=(1e-6, 100.0)),
    "acceleration": Param("float", check="positive", help="tangential acceleration bound [m/s^2]", bounds=(1e-6, 1e5)),
    "normal_acceleration": Param("float", 0.0, "nonnegative", help="centripetal acceleration bound, 0: none [m/s^2]",
                                 bounds=(0.0, 1e5)),
    "samples": Param("int", 20001, "positive", help="points of the feedrate profile table", bounds=(2, 1_000_000)),
    # the jerk-limited feed plan of a tool path (core/feed_planning.py); jerk 0: not jerk-limited
    "jerk": Param("float", 0.0, "nonnegative", help="path jerk bound, 0: no jerk limit [m/s^3]", bounds=(0.0, 1e7)),
    "rapid_feedrate": Param("float", 0.0, "nonnegative", help="G0 feedrate, 0: the commanded feedrate [m/s]",
                            bounds=(0.0, 100.0)),
    "axis_feedrate": Param("floats", None, help="per-axis speed bounds [m/s]", bounds=(1e-6, 100.0)),
    "axis_acceleration": Param("floats", None, help="per-axis acceleration bounds [m/s^2]", bounds=(1e-6, 1e5)),
    "axis_jerk": Param("floats", None, help="per-axis jerk bounds [m/s^3]", bounds=(1e-6, 1e7)),
    "contour_tolerance": Param("float", 0.0, "nonnegative", help="lower the feed where the predicted contour error "
                                                                 "exceeds this, 0: off [m]", bounds=(0.0, 1e-2)),
    "tracking_lag": Param("floats", None, help=f"each axis' tracking lag for the contour-error prediction {_S}",
                          bounds=(0.0, 10.0)),
    "exact_stop_dwell": Param("float", 0.0, "nonnegative", help=f"dwell at each exact-stop corner {_S}",
                              bounds=(0.0, 60.0)),
    "feed_override": Param("float", 100.0, "positive", help="feed override [percent of every programmed feed, rapids "
                                                            "included]", bounds=(1.0, 1000.0)),
    # LinuxCNC's queue holds 2000 segments, TwinCAT 120 to 500 blocks, Heidenhain up to 5000
    "lookahead_blocks": Param("int", LOOKAHEAD_BLOCKS, "nonnegative", help="blocks of the tool path the feed plan "
                              "sees ahead of the one it plans (0: the whole program)", bounds=(0, 10_000_000)),
    "in_position_timeout": Param("float", 0.5, "positive", help="the longest the reference waits at one exact stop "
                                                                f"for the axes {_S}", bounds=(1e-3, 60.0)),
}, _feedrate_schedule))
