"""A method's gains: which keys of its controller section the tuning varies, and the sections with tuned gains
set (a per-axis list keeping its proportions). The protocol: :mod:`contouring_ros.studies.tuning`."""
from __future__ import annotations

from ..core.tuning_space import gain_magnitude
from ..experiment.catalogue import CONTROLLERS

__all__ = ["gain_keys", "section_with_gains", "sections_with_gains"]


def gain_keys(controller: str, section: dict) -> tuple:
    """The gains of a controller section that the tuning varies (those the section sets): its catalogue
    entry's ``gains``; where the entry names none (a plugin's), its float parameters whose names start
    with 'k'."""
    entry = CONTROLLERS.entry(controller)
    keys = entry.gains
    if keys is None:
        keys = tuple(k for k, p in entry.params.items() if p.kind in ("float", "floats") and k.startswith("k"))
    return tuple(k for k in keys if section.get(k) is not None)


def _set_gain(section: dict, key: str, magnitude: float) -> None:
    """The gain ``key`` of ``section`` set to ``magnitude`` (a per-axis list keeps its proportions; a list
    of zeros becomes ``magnitude`` on every axis)."""
    value = section.get(key, magnitude)
    if isinstance(value, list):
        top = gain_magnitude(value)
        section[key] = [magnitude * float(v) / top for v in value] if top > 0 else [magnitude] * len(value)
    else:
        section[key] = magnitude


def section_with_gains(section: dict, gains: dict) -> dict:
    """A copy of the controller ``section`` with the tuned ``gains`` (key -> magnitude, as a
    :class:`~contouring_ros.studies.tuning.Tuned` and the benchmark's CSV give them) set."""
    out = dict(section)
    for key, magnitude in gains.items():
        _set_gain(out, key, magnitude)
    return out


def sections_with_gains(sections: dict, gains: dict) -> dict:
    """A copy of the node ``sections`` with raw ``gains`` set: a plain key on ``/ccc``, ``<axis>/servo.<key>``
    on that servo (a per-axis list keeps its proportions, :func:`_set_gain`)."""
    ccc = {k: v for k, v in gains.items() if "/" not in k}
    out = dict(sections, **{"/ccc": section_with_gains(sections["/ccc"], ccc)})
    for key, value in gains.items():
        if "/" in key:
            node, name = key.split(".", 1)
            out[f"/{node}"] = section_with_gains(out[f"/{node}"], {name: value})
    return out
