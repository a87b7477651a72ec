"""The schema of an experiment file: the layout keys, :class:`Param` (one expected key: kind, default, check,
bounds, meaning), the limits on what a file may hold, the ranges the catalogue's types share, and the checks
of one value or one mapping against its specs, with the one-line messages that name the file and the key."""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass

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
    bounds: tuple | None = None   # (low, high), inclusive, for every number of the value (None: DEFAULT_BOUNDS
                                  # of its kind)


# --- bounds: every number a file gives lies in a stated range, so no run starts that cannot end or fit --------
MAX_FILE_BYTES = 1 << 20        # an experiment file (UTF-8 text) is at most 1 MiB
MAX_PROGRAM_BYTES = 256 << 20   # a part program at most 256 MiB (a million short blocks take tens of MB)
MAX_PROGRAM_LINES = 2_000_000   # ... and at most this many lines: a chord held as a tool path and planned takes about 0.7 kB
#                                 (bench/long_programs.py), so a program stays within about 1.4 GB
MAX_DEPTH = 16                  # levels of YAML nesting (the shipped files use 6)
MAX_STEPS = 10_000_000          # control steps of one run: duration / sample_time + 1
MAX_DURATION = 3600.0           # s of simulated time
MAX_ITEMS = 4096                # items of one list
MAX_EVENTS = 20_000             # YAML parser events of one file (values, keys, collections); a scenario has ~300
MAX_TEXT = 256                  # characters of one string value
NUMERIC_KINDS = ("float", "int", "floats")
#: the range of a number whose Param states none (a plugin's): its kind's
DEFAULT_BOUNDS = {"float": (-1e12, 1e12), "floats": (-1e12, 1e12), "int": (-2 ** 31, 2 ** 31 - 1)}
# ranges the catalogue's types share (each Param states its own; these name the common ones)
GAIN_RANGE, POSITIVE_RANGE = (0.0, 1e12), (1e-12, 1e12)
SIZE_RANGE, COORDINATE_RANGE = (1e-9, 1e3), (-1e3, 1e3)                # m
MASS_RANGE, DAMPING_RANGE, FORCE_RANGE = (1e-9, 1e9), (0.0, 1e9), (0.0, 1e9)   # kg, N s/m, N
AXIS_GAIN_RANGE, TIME_CONSTANT_RANGE = (1e-9, 1e9), (1e-6, 1e3)        # command units -> m/s (or N); s
SEED_RANGE = (0, 2 ** 32 - 1)
BANDWIDTH_RANGE = (1e-6, 1e5)                                          # Hz

LIMIT = Param("float", 0.0, "nonnegative", help="output limit in command units, 0: none (anti-windup when hit)",
              bounds=GAIN_RANGE)


def limit(help: str) -> Param:
    """An output or command limit (0: none), described by ``help``."""
    return Param("float", 0.0, "nonnegative", help=help, bounds=GAIN_RANGE)


def pid_gains(limit_help: str, **defaults) -> dict:
    """kp, ki, kd (nonnegative; REQUIRED unless ``defaults`` gives one) and output_limit."""
    units = {"kp": "proportional gain [command units/m]", "ki": "integral gain [command units/(m s)]",
             "kd": "derivative gain [command units s/m]"}
    gains = {name: Param("float", defaults.get(name, REQUIRED), "nonnegative", help=units[name], bounds=GAIN_RANGE)
             for name in units}
    return {**gains, "output_limit": limit(limit_help)}


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
    if kind in ("float", "floats") and not all(math.isfinite(v) for v in (value if kind == "floats" else [value])):
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
