"""Plants (core/plants.py): each ``/<axis>/plant`` section, one feed drive. Every type also takes the
imperfections of a real drive (encoder quantisation, measurement noise, computation delay, the velocity
reading), all off by default. ``varied``: the physical parameters the benchmark's robustness checks and
model-mismatch draws vary (contouring_ros/studies/machine.py)."""
from __future__ import annotations

from ...core import plants
from ...core.tuning_space import first_order_response, mass_damper_response
from ..registry import Entry, Role
from ..schema import AXIS_GAIN_RANGE, DAMPING_RANGE, FORCE_RANGE, MASS_RANGE, SEED_RANGE, TIME_CONSTANT_RANGE, Param, limit
from .disturbances import DISTURBANCES, build_disturbance

__all__ = ["PLANTS", "DISTURBANCE_UNITS", "MACHINE"]

PLANTS = Role("plant", "model", description="plant model")
DISTURBANCE_UNITS = ("command", "acceleration")

#: the imperfections of a real feed drive, every plant type (core/plants.py, Axis)
MACHINE = {
    "encoder_resolution": Param("float", 0.0, "nonnegative", help="position quantisation, 0: none [m]",
                                bounds=(0.0, 1.0)),
    "measurement_noise": Param("float", 0.0, "nonnegative", help="standard deviation of the white Gaussian noise on "
                               "the position reading, 0: none [m]", bounds=(0.0, 1.0)),
    "noise_seed": Param("int", 0, "nonnegative", help="seed of the measurement noise (same seed, same noise)",
                        bounds=SEED_RANGE),
    "command_delay": Param("int", 0, "nonnegative", help="computation delay: a command acts this many periods after "
                           "it is computed [samples]", bounds=(0, plants.MAX_COMMAND_DELAY)),
    "velocity_measurement": Param("str", "model", choices=plants.VELOCITY_MEASUREMENTS,
                                  help="the velocity reading: the drive's own (model) or the differentiated encoder"),
}
_GAIN = Param("float", check="positive", help="actuator gain [m/s per command unit (velocity axis), N per command "
                                              "unit (mass)]", bounds=AXIS_GAIN_RANGE)
_DISTURBANCE = Param("dict", {"type": "none"}, choices=DISTURBANCES, help="load disturbance")
_SATURATION = limit("command limit, 0: none [command units]")


def _machine(s) -> dict:
    return {key: s[key] for key in MACHINE}


PLANTS.add(Entry("first_order_velocity", {
    "gain": _GAIN,
    "time_constant": Param("float", check="positive", help="velocity loop time constant [s]",
                           bounds=TIME_CONSTANT_RANGE),
    "disturbance": _DISTURBANCE, "saturation": _SATURATION, **MACHINE,
}, lambda s, c: plants.FirstOrderVelocityAxis(
    s["gain"], s["time_constant"], c.sample_time, build_disturbance(s["disturbance"]), c.position, c.velocity,
    s["saturation"], **_machine(s)), varied=("gain", "time_constant"), response=first_order_response))
PLANTS.add(Entry("mass_damper", {
    "mass": Param("float", check="positive", help="moving mass [kg]", bounds=MASS_RANGE),
    "damping": Param("float", check="nonnegative", help="viscous damping [N s/m]", bounds=DAMPING_RANGE),
    "gain": _GAIN,
    "coulomb_positive": Param("float", 0.0, "nonnegative", help="Coulomb friction moving forward [N]",
                              bounds=FORCE_RANGE),
    "coulomb_negative": Param("float", 0.0, "nonnegative", help="Coulomb friction moving back [N]",
                              bounds=FORCE_RANGE),
    "disturbance": _DISTURBANCE,
    "disturbance_unit": Param("str", "command", choices=DISTURBANCE_UNITS, help="what the disturbance is given in"),
    "saturation": _SATURATION, **MACHINE,
}, lambda s, c: plants.MassDamperAxis(
    s["mass"], s["damping"], s["gain"], c.sample_time, build_disturbance(s["disturbance"]), c.position,
    c.velocity, s["saturation"], s["coulomb_positive"], s["coulomb_negative"], s["disturbance_unit"],
    **_machine(s)), varied=("mass", "damping", "gain"), response=mass_damper_response))
