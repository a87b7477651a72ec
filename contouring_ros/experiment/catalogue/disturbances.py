"""Load disturbances of a plant (core/disturbances.py): the plant section's ``disturbance`` mapping."""
from __future__ import annotations

from ...core import disturbances
from ..registry import Entry, Role, section_arguments
from ..schema import SEED_RANGE, Param

__all__ = ["DISTURBANCES", "build_disturbance"]

DISTURBANCES = Role("disturbance", description="disturbance type")

LOAD_RANGE = (-1e9, 1e9)      # command units or m/s^2 (the plant's disturbance_unit)
_OFFSET = Param("float", 0.0, help="offset [command units or m/s^2]", bounds=LOAD_RANGE)

for _entry in (
    Entry("none", {}, lambda s, c: disturbances.NoDisturbance()),
    Entry("constant", {"value": Param("float", help="constant disturbance [command units or m/s^2]", bounds=LOAD_RANGE)},
          lambda s, c: disturbances.ConstantDisturbance(s["value"])),
    Entry("sinusoid", {"amplitude": Param("float", help="amplitude [command units or m/s^2]", bounds=LOAD_RANGE),
                       "frequency": Param("float", check="positive", help="frequency [Hz]", bounds=(1e-6, 1e5)),
                       "phase": Param("float", 0.0, help="phase [rad]", bounds=(-1e3, 1e3)), "offset": _OFFSET},
          lambda s, c: disturbances.SinusoidalDisturbance(**section_arguments(s))),
    Entry("random", {"std": Param("float", check="nonnegative", help="standard deviation [command units or m/s^2]",
                                  bounds=(0.0, 1e9)),
                     "seed": Param("int", 0, "nonnegative", help="random seed", bounds=SEED_RANGE), "offset": _OFFSET},
          lambda s, c: disturbances.RandomDisturbance(**section_arguments(s))),
):
    DISTURBANCES.add(_entry)


def build_disturbance(section: dict):
    """The disturbance of a validated ``disturbance`` mapping."""
    return DISTURBANCES.build(section)
