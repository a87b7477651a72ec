"""The schema of an experiment file: the layout keys, :class:`Param` (one expected key: kind, default, check,
bounds), the limits on what a file may hold, the bounds of every number by role and key, and the checks of
one value or one mapping against its specs, with the one-line messages that name the file and the key."""
from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from ..core import plants
from ..errors import ConfigError

GLOBAL_SECTION = "/**"
ROS_PARAMETERS = "ros__parameters"
REQUIRED = object()


@dataclass(frozen=True)
class Param:
    """One expected key: its kind, default (REQUIRED if none), and the range it must lie in."""

    kind: str                     # float | int | str | bool | floats | strings | dict
    default: object = REQUIRED
    check: str | None = None      # positive | nonnegative
    choices: dict | tuple | None = None   # kind "dict" with a 'type': the registry of its types; kind "str": the
                                          # names allowed
    help: str = ""
    bounds: tuple | None = None   # (low, high), inclusive, for every number of the value (BOUNDS sets them;


LIMIT = Param("float", 0.0, "nonnegative", help="output limit in command units, 0: none (anti-windup when hit)")


def _gains(**defaults):
    gains = {name: Param("float", defaults.get(name, REQUIRED), "nonnegative") for name in ("kp", "ki", "kd")}
    return {**gains, "output_limit": LIMIT}


# --- bounds: every number a file gives lies in a stated range, so no run starts that cannot end or fit --------
MAX_FILE_BYTES = 1 << 20        # an experiment file (UTF-8 text) is at most 1 MiB
MAX_PROGRAM_BYTES = 256 << 20   # a part program at most 256 MiB (a million short blocks take tens of MB)
MAX_DEPTH = 16                  # levels of YAML nesting (the shipped files use 6)
MAX_STEPS = 10_000_000          # control steps of one run: duration / sample_time + 1
MAX_DURATION = 3600.0           # s of simulated time
MAX_ITEMS = 4096                # items of one list
MAX_EVENTS = 20_000             # YAML parser events of one file (values, keys, collections); a scenario has ~300
MAX_TEXT = 256                  # characters of one string value
NUMERIC_KINDS = ("float", "int", "floats")
DEFAULT_BOUNDS = {"float": (-1e12, 1e12), "floats": (-1e12, 1e12), "int": (-2 ** 31, 2 ** 31 - 1)}
_GAIN, _POSITIVE, _LIMIT = (0.0, 1e12), (1e-12, 1e12), (0.0, 1e12)
_SIZE, _COORDINATE = (1e-9, 1e3), (-1e3, 1e3)              # m
_MASS, _DAMPING, _FORCE = (1e-9, 1e9), (0.0, 1e9), (0.0, 1e9)
_AXIS_GAIN, _TIME_CONSTANT = (1e-9, 1e9), (1e-6, 1e3)      # command units -> m/s (or N); s
# registry -> {key: (low, high)} for that key in every type of the registry, or {"type.key": ...} for one type
BOUNDS = {
    "GLOBALS": {"sample_time": (1e-5, 1.0), "duration": (0.0, MAX_DURATION), "settle_time": (0.0, MAX_DURATION),
                "stall_timeout": (1e-3, 3600.0), "graph_timeout": (1e-3, 86400.0), "start_time": (0.0, 1e10),
                "divergence_factor": (0.0, 1e6), "max_lag": (1e-6, 3600.0),
                "in_position": (0.0, 1e-2)},
    "CURVES": {"a": _SIZE, "b": _SIZE, "radius": _SIZE, "scale": _SIZE, "length": (1e-9, 1e6), "h": (-1e3, 1e3),
               "c": (-1e3, 1e3), "omega": (-1e4, 1e4), "center": _COORDINATE, "start": _COORDINATE,
               "end": _COORDINATE, "x": _COORDINATE, "y": _COORDINATE, "z": _COORDINATE,
               "contour_error_window": (0.0, 1e6), "blend_tolerance": (0.0, 1e-2)},
    "SCHEDULES": {"theta_start": (-1e6, 1e6), "theta_end": (-1e6, 1e6), "duration": (1e-6, MAX_DURATION),
                  "feedrate": (1e-6, 100.0), "acceleration": (1e-6, 1e5), "normal_acceleration": (0.0, 1e5),
                  "samples": (2, 1_000_000), "jerk": (0.0, 1e7), "rapid_feedrate": (0.0, 100.0),
                  "axis_feedrate": (1e-6, 100.0), "axis_acceleration": (1e-6, 1e5), "axis_jerk": (1e-6, 1e7),
                  "contour_tolerance": (0.0, 1e-2), "tracking_lag": (0.0, 10.0), "exact_stop_dwell": (0.0, 60.0),
                  "feed_override": (1.0, 1000.0), "in_position_timeout": (1e-3, 60.0)},
    "DISTURBANCES": {"value": (-1e9, 1e9), "amplitude": (-1e9, 1e9), "offset": (-1e9, 1e9),
                     "frequency": (1e-6, 1e5), "phase": (-1e3, 1e3), "std": (0.0, 1e9), "seed": (0, 2 ** 32 - 1)},
    "PLANTS": {"gain": _AXIS_GAIN, "time_constant": _TIME_CONSTANT, "mass": _MASS, "damping": _DAMPING,
               "coulomb_positive": _FORCE, "coulomb_negative": _FORCE, "saturation": _LIMIT,
               "encoder_resolution": (0.0, 1.0), "measurement_noise": (0.0, 1.0), "noise_seed": (0, 2 ** 32 - 1),
               "command_delay": (0, plants.MAX_COMMAND_DELAY)},
    "SERVOS": {"kp": _GAIN, "ki": _GAIN, "kd": _GAIN, "kp_position": _GAIN, "kp_velocity": _GAIN,
               "ki_velocity": _GAIN, "output_limit": _LIMIT, "gain": _AXIS_GAIN, "time_constant": _TIME_CONSTANT,
               "pid_feedforward.time_constant": (0.0, 1e3), "a": _POSITIVE, "b": _POSITIVE, "mu": _POSITIVE,
               "kappa": _POSITIVE, "c": _POSITIVE, "d": _POSITIVE, "k": _POSITIVE, "sigma": _POSITIVE,
               "alphas": _GAIN, "mass": _MASS, "damping": _DAMPING, "coulomb_positive": _FORCE,
               "coulomb_negative": _FORCE},
    "ESTIMATORS": {"foot_point_search.max_iterations": (1, 1000), "newton.max_iterations": (1, 10_000),
                   "tolerance": (1e-15, 1.0), "k_prime": _POSITIVE, "c_prime": _POSITIVE, "inner_step": (0.0, 1.0),
                   "theta0": (-1e6, 1e6), "branch_check_samples": (0, 10_000),
                   "branch_check_tolerance": (1e-15, 1e3)},
    "CONTROLLERS": {"kp": _GAIN, "ki": _GAIN, "kd": _GAIN, "output_limit": _LIMIT, "mass": _MASS,
                    "damping": _DAMPING, "gain": _AXIS_GAIN, "coulomb_positive": _FORCE, "coulomb_negative": _FORCE,
                    "f_t": (1e-6, 1e5), "f_n": (1e-6, 1e5), "f_b": (1e-6, 1e5), "zeta": (1e-6, 1e3), "kc": _GAIN,
                    "min_feedrate": (0.0, 100.0), "coupling": (-1e12, 1e12), "alpha": _POSITIVE,
                    "gamma_mass": _GAIN, "gamma_damping": _GAIN, "mass0": _MASS, "damping0": _DAMPING},
}


def _described(value, kind=None) -> str:
    kind = kind or {bool: "bool", int: "integer", float: "double", str: "string"}.get(type(value))
    if value is None:
        return "null"
    if kind == "bool":
        return f"the boolean {str(value).lower()}"
    if kind == "integer":
        return f"the integer {_show(value)}"
    if kind == "double":
        return f"the number {value!r}"
    if kind == "string":
        return f"the string {_show(value)}"
    return f"a {type(value).__name__} ({_show(value)})"


def _show(value, limit: int = 60) -> str:
    """repr of a value for a one-line message, cut to ``limit`` characters."""
    text = repr(value) if not isinstance(value, int) or value.bit_length() < 100 else \
        f"an integer of {value.bit_length()} bits"
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _printable(text, limit: int = 300) -> str:
    """``text`` on one line: control characters escaped, cut to ``limit`` characters."""
    text = "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(text))
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _key_name(path) -> str:
    """The key a path of YAML keys names, as messages name it: 'curve.a' in the shared section, '/x/plant.gain'
    in a node's, list items as [i]."""
    if not path:
        return ""
    section, rest = str(path[0]), [str(part) for part in path[1:]]
    if rest and rest[0] == ROS_PARAMETERS:
        rest = rest[1:]
    parts = [] if section == GLOBAL_SECTION and rest else [section]
    for part in rest:
        parts.append(part if not parts or not part.startswith("[") else parts.pop() + part)
    return _printable(".".join(parts), 80)


def _fail(where: str, key: str, message: str):
    where, key, message = _printable(where), _printable(key, 80), _printable(message, 400)
    raise ConfigError(f"{where}: {key}: {message}" if key else f"{where}: {message}")


def _value(where, key, spec: Param, value):
    """Check one value against its spec and return it normalised."""
    kind = spec.kind
    if kind in ("float", "int", "floats") and isinstance(value, int) and not isinstance(value, bool) and \
            value.bit_length() > 63:
        _fail(where, key, f"expected a value from {(spec.bounds or DEFAULT_BOUNDS[kind])[0]:g} to "
                          f"{(spec.bounds or DEFAULT_BOUNDS[kind])[1]:g}, got {_show(value)}")
    if kind == "float":
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            _fail(where, key, f"expected a number, got {_show(value)}")
        value = float(value)
    elif kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            _fail(where, key, f"expected an integer, got {_show(value)}")
    elif kind == "bool":
        if not isinstance(value, bool):
            _fail(where, key, f"expected true or false, got {_show(value)}")
    elif kind == "str":
        if not isinstance(value, str):
            _fail(where, key, f"expected a string, got {_show(value)}")
        _check_text(where, key, value)
        if spec.choices is not None and value not in spec.choices:
            _fail(where, key, f"expected one of {', '.join(spec.choices)}, got {_show(value)}")
    elif kind == "floats":
        if not isinstance(value, (list, tuple)) or not value or any(
                isinstance(v, bool) or not isinstance(v, (int, float)) for v in value):
            _fail(where, key, f"expected a list of numbers, got {_show(value)}")
        if len(value) > MAX_ITEMS:
            _fail(where, key, f"expected at most {MAX_ITEMS} items, got {len(value)}")
        for index, v in enumerate(value):
            if isinstance(v, int) and v.bit_length() > 63:
                _fail(where, key, f"item {index + 1}: expected a number from {(spec.bounds or DEFAULT_BOUNDS[kind])[0]:g}"
                                  f" to {(spec.bounds or DEFAULT_BOUNDS[kind])[1]:g}, got {_show(v)}")
        value = [float(v) for v in value]
    elif kind == "strings":
        if not isinstance(value, (list, tuple)) or not value or any(not isinstance(v, str) for v in value):
            _fail(where, key, f"expected a non-empty list of names, got {_show(value)}")
        if len(value) > MAX_ITEMS:
            _fail(where, key, f"expected at most {MAX_ITEMS} items, got {len(value)}")
        for v in value:
            _check_text(where, key, v)
        value = list(value)
    elif kind == "dict":
        if not isinstance(value, dict):
            _fail(where, key, f"expected a mapping, got {_show(value)}")
        if spec.choices is not None:
            value = _typed(where, key, "type", spec.choices, value)
    if spec.check == "positive" and not value > 0:
        _fail(where, key, f"expected a positive value, got {_show(value)}")
    if spec.check == "nonnegative" and not value >= 0:
        _fail(where, key, f"expected a value >= 0, got {_show(value)}")
    if kind in ("float", "floats") and not np.all(np.isfinite(value)):
        _fail(where, key, f"expected finite numbers, got {_show(value)}")
    if kind in NUMERIC_KINDS:
        _check_bounds(where, key, spec, value)
    return value


def _check_bounds(where, key, spec: Param, value):
    """Every number of ``value`` within the spec's bounds (or its kind's), and no float denormal."""
    low, high = spec.bounds or DEFAULT_BOUNDS[spec.kind]
    for index, number in enumerate(value if spec.kind == "floats" else [value]):
        item = f"item {index + 1} " if spec.kind == "floats" else ""
        if spec.kind != "int" and number != 0 and abs(number) < sys.float_info.min:
            _fail(where, key, f"{item}{number!r} is a denormal number (below {sys.float_info.min:.3g} in size)")
        if not low <= number <= high:
            _fail(where, key, f"{item}expected a value from {low:g} to {high:g}, got {_show(number)}")


def _check_text(where, key, text: str):
    """A string value: at most MAX_TEXT characters, no control characters (NUL, newlines ...)."""
    if len(text) > MAX_TEXT:
        _fail(where, key, f"expected at most {MAX_TEXT} characters, got {len(text)}")
    if not text.isprintable():
        _fail(where, key, f"control characters (NUL, line breaks ...) are not allowed, got {_show(text)}")


# keys renamed between versions: old name -> (new name, what changed); an experiment file that still uses the
# old name is told the new one (where the section has it) instead of "unknown key"
RENAMED_KEYS = {
    "iterations": ("max_iterations", "the Newton estimator iterates each step until it is within `tolerance`, "
                                     "at most max_iterations times"),
}


def _mapping(where, prefix, specs: dict, given: dict, skip=()) -> dict:
    """Validate a mapping against ``specs``: unknown keys, missing required keys, each value."""
    out = {}
    for key in given:
        if key not in specs and key not in skip:
            renamed = RENAMED_KEYS.get(key)
            if renamed is not None and renamed[0] in specs:
                _fail(where, f"{prefix}{key}", f"`{key}` is now `{renamed[0]}` ({renamed[1]}): rename the key")
            known = ", ".join(sorted(specs)) or "none"
            _fail(where, f"{prefix}{key}", f"unknown key (expected one of: {known})")
    for key, spec in specs.items():
        if key in given:
            out[key] = _value(where, f"{prefix}{key}", spec, given[key])
        elif spec.default is REQUIRED:
            _fail(where, f"{prefix}{key}", "missing required key")
        else:
            out[key] = spec.default if spec.kind != "dict" or spec.choices is None else \
                _typed(where, f"{prefix}{key}", "type", spec.choices, dict(spec.default))
    return out


def _typed(where, prefix, type_key, registry: dict, given: dict) -> dict:
    """Validate a section that names its implementation with ``type_key`` (type, law, model)."""
    name = given.get(type_key)
    if name is None:
        _fail(where, f"{prefix}.{type_key}", f"missing required key (one of: {', '.join(registry)})")
    if name not in registry:
        _fail(where, f"{prefix}.{type_key}", f"unknown name {name!r} (expected one of: {', '.join(registry)})")
    out = _mapping(where, f"{prefix}.", registry[name], given, skip=(type_key,))
    out[type_key] = name
    return out
