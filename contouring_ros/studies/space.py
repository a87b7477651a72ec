"""Where a combination is searched: its tuning space, from its controller's catalogue entry (else the log box
of its raw gains) and its servo law's where that states one (the ZPETC's PID), in physical coordinates
(:mod:`contouring_ros.core.tuning_space`), a linear PID's at a chosen Ms of its loops on the machine. The
protocol: :mod:`contouring_ros.studies.tuning`."""
from __future__ import annotations

from ..core.tuning_space import Space, TuningContext, combine, log_box
from ..experiment.catalogue import CONTROLLERS, PLANTS, SERVOS
from .loops import scaled_loops, servo_loops
from .outcomes import experiment_for
from .tuning import Protocol

__all__ = ["tuned_servo", "tuning_space"]


def tuned_servo(experiment):
    """The catalogue entry of the experiment's servo law where every axis has the same law and that law
    states a tuning space of its own (the ZPETC's PID), else None."""
    laws = {experiment.servos[a]["law"] for a in experiment.axes}
    entry = SERVOS.entry(laws.pop()) if len(laws) == 1 else None
    return entry if entry is not None and entry.tuning is not None else None


def tuning_space(data: dict, sections: dict, keys: tuple, protocol: Protocol, where: str = "tuning",
                 machine: dict | None = None) -> tuple:
    """(the space a combination is tuned in, the validated sections its file point is read from): its
    controller's catalogue ``tuning`` space (else the log box of its raw gains ``keys``,
    :func:`contouring_ros.core.tuning_space.log_box`; none without either), with the space of the servos
    added where their law states one (the ZPETC's PID). A linear PID contour controller is searched at a chosen
    Ms of its coupled loops on the ``machine`` (grid settings; :func:`~contouring_ros.studies.loops.scaled_loops`),
    where the protocol bounds Ms and the servos' gains stay the file's; a servo law's PID that is tuned too (the
    ZPETC's) at a chosen Ms of each axis' own loop on the machine
    (:func:`~contouring_ros.studies.loops.servo_loops`)."""
    experiment = experiment_for(data, sections, {}, where)
    axes = list(experiment.axes)
    responses = {}
    for a in axes:
        plant = experiment.plants[a]
        entry = PLANTS.entry(plant["model"])
        responses[a] = (lambda w, e=entry, s=plant: e.response(s, w)) if entry.response else None
    servo_entry = tuned_servo(experiment)
    scaled = scaled_loops(data, sections, machine or {}, where) if protocol.ms_limit and servo_entry is None else None
    servos = servo_loops(experiment_for(data, sections, machine or {}, where)) \
        if protocol.ms_limit and servo_entry is not None else {}
    context = TuningContext(float(experiment.sample_time), dict(experiment.plants), dict(experiment.servos), responses,
                            scaled, servos)
    validated = {"/ccc": experiment.controller, **{f"/{a}/servo": experiment.servos[a] for a in axes}}
    entry = CONTROLLERS.entry(experiment.controller["type"])
    space = entry.tuning(experiment.controller, context) if entry.tuning else None
    if space is None and keys:
        space = log_box(experiment.controller, keys, protocol.decades)
    if servo_entry is not None:
        space = combine(space, servo_entry.tuning(experiment.servos[axes[0]], context))
    return space or Space((), lambda values: {}, lambda sections: {}, "none"), validated
