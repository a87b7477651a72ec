"""Servo laws (core/servo.py): each ``/<axis>/servo`` section, one axis' position loop. ``direct``: the law
passes the contour controller's output through (for controllers that compute the whole command);
``preview``: how many steps of reference beyond the current one the law reads (the interpolator publishes
them with each reference)."""
from __future__ import annotations

from ...core import servo
from ...core.plants import MAX_COMMAND_DELAY
from ..registry import Entry, Role
from ...core.tuning_space import pid_servo_space
from ..schema import AXIS_GAIN_RANGE, DAMPING_RANGE, FORCE_RANGE, GAIN_RANGE, MASS_RANGE, POSITIVE_RANGE, REQUIRED, \
    TIME_CONSTANT_RANGE, Param, limit, pid_gains
from .curves import TOOL_PATH_TYPES

__all__ = ["SERVOS", "plan_correction"]

SERVOS = Role("servo", "law", description="servo law")

_LIMIT = "command limit, 0: none (anti-windup when hit) [command units]"
_MODEL_GAIN = Param("float", check="positive", help="model actuator gain [m/s per command unit]", bounds=AXIS_GAIN_RANGE)


def _positive(help: str, default=REQUIRED) -> Param:
    return Param("float", default, "positive", help=help, bounds=POSITIVE_RANGE)


def _force(help: str) -> Param:
    return Param("float", 0.0, "nonnegative", help=help, bounds=FORCE_RANGE)


def plan_correction(section: dict, experiment) -> bool:
    """Whether an ISMC servo's disturbance estimate gets the plan correction: the section's
    ``observer_plan_correction`` where given, else on a tool path only (whose feed plan has jerk phases:
    paper 000's own experiments keep the paper's eq. 25)."""
    given = section["observer_plan_correction"]
    if given is not None:
        return bool(given)
    return experiment is not None and experiment.curve["type"] in TOOL_PATH_TYPES


def _check_zpetc(section, axes):
    if not section["kp"] and not section["ki"]:
        return "kp", "the zpetc law inverts its loop from the reference to the position: kp or ki must be positive"
    return None


def _zpetc(s, c):
    return servo.ZPETCServo(s["kp"], s["ki"], s["kd"], s["gain"], s["time_constant"], c.sample_time,
                            s["command_delay"], s["zero_radius"], s["output_limit"])


def _ismc(s, c):
    ts = c.sample_time
    observer = servo.DisturbanceObserver(s["c"], s["d"], s["gain"], s["time_constant"], ts, c.velocity,
                                         c.acceleration, plan_correction(s, c.experiment)) if s["observer"] else None
    return servo.IntegralSlidingModeServo(s["a"], s["b"], s["mu"], s["kappa"], s["gain"], s["time_constant"],
                                          ts, observer, s["output_limit"])


def _check_eso_smc(section, axes):
    if len(section["alphas"]) != 3:
        return "alphas", f"expected the three ESO gains alpha_1..3, got {len(section['alphas'])}"
    return None


for _entry in (
    Entry("pid_feedforward", {
        **pid_gains(_LIMIT), "gain": _MODEL_GAIN,
        "time_constant": Param("float", check="nonnegative", help="model time constant [s]", bounds=(0.0, 1e3))},
        lambda s, c: servo.PIDFeedforwardServo(s["kp"], s["ki"], s["kd"], s["gain"], s["time_constant"],
                                               c.sample_time, s["output_limit"])),
    Entry("ismc", {
        "a": _positive("sliding surface gain a [1/s]"), "b": _positive("sliding surface gain b [1/s^2]"),
        "mu": _positive("boundary layer width"), "kappa": _positive("switching gain"), "gain": _MODEL_GAIN,
        "time_constant": Param("float", check="positive", help="model time constant [s]", bounds=TIME_CONSTANT_RANGE),
        "observer": Param("bool", False, help="use the disturbance observer"),
        "c": _positive("observer gain c [1/s]", 1.0),
        # None: true on a tool path, else false
        "observer_plan_correction": Param("bool", None, help="add to eq. 25 its filter mismatch computed on the "
                                          "reference (not in the paper): the plan's jerk no longer read as load"),
        "d": _positive("observer gain d [1/s^2]", 1.0), "output_limit": limit(_LIMIT)},
        _ismc),
    Entry("direct", {"output_limit": limit(_LIMIT)}, lambda s, c: servo.DirectServo(s["output_limit"]), direct=True),
    Entry("pid", pid_gains(_LIMIT, ki=0.0, kd=0.0),
          lambda s, c: servo.PIDServo(s["kp"], s["ki"], s["kd"], c.sample_time, s["output_limit"])),
    Entry("cascade", {
        "kp_position": Param("float", check="nonnegative", help="position loop gain [1/s]", bounds=GAIN_RANGE),
        "kp_velocity": Param("float", check="nonnegative", help="velocity loop gain [command units s/m]",
                             bounds=GAIN_RANGE),
        "ki_velocity": Param("float", 0.0, "nonnegative", help="velocity loop integral gain [command units/m]",
                             bounds=GAIN_RANGE),
        "coulomb_positive": _force("model Coulomb friction forward [N]"),
        "coulomb_negative": _force("model Coulomb friction back [N]"), "output_limit": limit(_LIMIT)},
        lambda s, c: servo.CascadeServo(s["kp_position"], s["kp_velocity"], s["ki_velocity"], c.sample_time,
                                        s["coulomb_positive"], s["coulomb_negative"], s["output_limit"])),
    Entry("eso_smc", {
        "mass": Param("float", check="positive", help="model mass [kg]", bounds=MASS_RANGE),
        "damping": Param("float", check="nonnegative", help="model damping [N s/m]", bounds=DAMPING_RANGE),
        "gain": _MODEL_GAIN, "c": _positive("observer gain c [1/s]"), "k": _positive("sliding gain k"),
        "alphas": Param("floats", help="extended state observer gains", bounds=GAIN_RANGE),
        "sigma": _positive("boundary layer sigma"),
        "disturbance_compensation": Param("bool", True, help="subtract the observer's disturbance estimate"),
        "output_limit": limit(_LIMIT)},
        lambda s, c: servo.ESOSlidingModeServo(s["mass"], s["damping"], s["gain"], s["c"], s["k"], s["alphas"],
                                               s["sigma"], c.sample_time, c.position, c.velocity,
                                               s["disturbance_compensation"], s["output_limit"]),
        check=_check_eso_smc),
    Entry("zpetc", {
        **pid_gains(_LIMIT), "gain": _MODEL_GAIN,
        "time_constant": Param("float", check="positive", help="model time constant [s]", bounds=TIME_CONSTANT_RANGE),
        "command_delay": Param("int", 0, "nonnegative", help="the drive's computation delay the design assumes "
                               "[samples] (the plant's command_delay, where it is known)", bounds=(0, MAX_COMMAND_DELAY)),
        "zero_radius": Param("float", 0.5, "positive", help="a closed-loop zero on the negative real side with at "
                             "least this modulus is not inverted (nor any outside the unit circle)", bounds=(1e-3, 1.0))},
        _zpetc, check=_check_zpetc, preview=lambda s, experiment, axis: s["command_delay"] + 3,
        tuning=pid_servo_space),
):
    SERVOS.add(_entry)
