"""The realistic machine a combination is tuned on, and its draws: the plants' settings that make the file's
machine a real feed drive (encoder, noise, computation delay, velocity from the encoder, an actuator limit), the
methods' sections fitted to that drive, the robustness runs' perturbations and the interval's draws (noise seeds,
model mismatch, disturbance phase). The protocol: :mod:`contouring_ros.studies.tuning`."""
from __future__ import annotations

import math

import numpy as np

from ..experiment.catalogue import CONTROLLERS, PLANTS, SERVOS
from ..experiment.schema import GLOBAL_SECTION

__all__ = ["REALISTIC", "SATURATION_MARGIN", "varied_parameters", "machine_settings", "perturbations",
           "draw_settings", "actuator_limits", "fit_to_machine"]

#: plant keys of the realistic machine (a key the scenario file sets is kept)
REALISTIC = {"encoder_resolution": 1e-7, "measurement_noise": 5e-8, "command_delay": 1,
             "velocity_measurement": "encoder"}
#: the actuator limit, where the paper states none: this times the proposed method's largest command
SATURATION_MARGIN = 2.0


def varied_parameters(model) -> tuple:
    """The physical parameters of a plant type that robustness runs and model-mismatch draws vary: its
    catalogue entry's ``varied`` (none for a type not known)."""
    return PLANTS.entry(model).varied if isinstance(model, str) and model in PLANTS else ()


def _plants(data: dict) -> dict:
    """'/x/plant' -> its parameters, for every axis of the file."""
    axes = data[GLOBAL_SECTION]["ros__parameters"]["axes"]
    return {f"/{a}/plant": data[f"/{a}/plant"]["ros__parameters"] for a in axes}


def machine_settings(data: dict, kind: str, peak_command: tuple = ()) -> dict:
    """Grid settings (see :mod:`contouring_ros.studies.sweep`) that put the file's plants on a machine ``kind``:
    'ideal' (no settings) or 'realistic' (:data:`REALISTIC`, each key the file does not set; an actuator
    limit of :data:`SATURATION_MARGIN` x ``peak_command`` of the axis where the file sets none)."""
    if kind == "ideal":
        return {}
    if kind != "realistic":
        raise ValueError(f"machine {kind!r}: expected ideal or realistic")
    settings = {}
    for i, (node, params) in enumerate(_plants(data).items()):
        where = node[1:]
        for key, value in REALISTIC.items():
            if not params.get(key):
                settings[f"{where}.{key}"] = value
        if "noise_seed" not in params:                     # noise independent between the axes
            settings[f"{where}.noise_seed"] = i
        if not params.get("saturation") and i < len(peak_command) and peak_command[i] > 0:
            settings[f"{where}.saturation"] = SATURATION_MARGIN * float(peak_command[i])
    return settings


def perturbations(data: dict, fraction: float) -> list:
    """Settings for the robustness runs: each plant parameter of :func:`varied_parameters` at (1 - fraction)
    and (1 + fraction) of its value, on every axis at once."""
    plants = _plants(data)
    keys = []
    for params in plants.values():
        for key in varied_parameters(params.get("model")):
            if key not in keys and params.get(key):
                keys.append(key)
    out = []
    for key in keys:
        for factor in (1.0 - fraction, 1.0 + fraction):
            out.append({f"{node[1:]}.{key}": float(params[key]) * factor for node, params in plants.items()
                        if params.get(key)})
    return out


def draw_settings(data: dict, j: int, mismatch: float) -> dict:
    """Draw ``j``'s settings: noise seeds from j, every plant parameter x U(1 - mismatch, 1 + mismatch), and
    from draw 1 on a sinusoidal disturbance's phase U(0, 2 pi) and a random disturbance's seed (drawn from j
    alone, so every method of a scenario meets the same draws)."""
    rng = np.random.default_rng(1000 + j)
    settings = {}
    for i, (node, params) in enumerate(_plants(data).items()):
        settings[f"{node[1:]}.noise_seed"] = 1 + j * 16 + i
        for key in varied_parameters(params.get("model")):
            factor = float(rng.uniform(1.0 - mismatch, 1.0 + mismatch))
            if params.get(key):
                settings[f"{node[1:]}.{key}"] = float(params[key]) * factor
        phase = float(rng.uniform(0.0, 2.0 * math.pi))
        disturbance = params.get("disturbance") or {}
        if j and disturbance.get("type") == "sinusoid":
            settings[f"{node[1:]}.disturbance.phase"] = phase
        elif j and disturbance.get("type") == "random":
            settings[f"{node[1:]}.disturbance.seed"] = int(disturbance.get("seed", 0)) + 7919 * j
    return settings


def actuator_limits(data: dict, settings: dict) -> tuple:
    """Each axis' actuator limit with the grid ``settings`` applied to the plants of ``data`` (0: none)."""
    return tuple(float(settings.get(f"{node[1:]}.saturation", params.get("saturation") or 0.0))
                 for node, params in _plants(data).items())


def fit_to_machine(data: dict, sections: dict, machine: dict) -> dict:
    """``sections`` with what models the drive set to the machine's (``machine``: grid settings of
    :func:`machine_settings` over the plants of ``data``): a servo's or controller's ``command_delay`` the
    axis' computation delay (a controller: the largest), a controller's unset ``command_limit`` each axis'
    actuator limit (:func:`actuator_limits`), and where the machine's velocity is the differentiated encoder,
    a controller's unset ``velocity_estimate`` 'model' (its observer, not the mean velocity of the last step).
    A method that models its drive is told the drive it runs on, as an engineer commissioning it would be."""
    plants = _plants(data)
    delay = {node: int(machine.get(f"{node[1:]}.command_delay", params.get("command_delay") or 0))
             for node, params in plants.items()}
    limit = list(actuator_limits(data, machine))
    out = dict(sections)
    for node in plants:
        servo_node = node.replace("/plant", "/servo")
        servo = out.get(servo_node)
        if servo and "command_delay" in SERVOS.entry(servo["law"]).params:
            out[servo_node] = dict(servo, command_delay=delay[node])
    ccc = out.get("/ccc")
    if ccc and ccc.get("type") in CONTROLLERS:
        params = CONTROLLERS.entry(ccc["type"]).params
        ccc = dict(ccc)
        if "command_delay" in params:
            ccc["command_delay"] = max(delay.values())
        if "command_limit" in params and not any(ccc.get("command_limit") or ()) and any(limit):
            ccc["command_limit"] = limit
        encoder = any(machine.get(f"{node[1:]}.velocity_measurement", plant.get("velocity_measurement")) == "encoder"
                      for node, plant in plants.items())
        if "velocity_estimate" in params and "velocity_estimate" not in ccc and encoder:
            ccc["velocity_estimate"] = "model"
        out["/ccc"] = ccc
    return out
