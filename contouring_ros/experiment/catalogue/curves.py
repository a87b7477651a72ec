"""Curves (core/curves.py): the shared section's ``curve`` mapping. Every built-in curve also takes
``contour_error_window``, the half-width of the exact contour error's search."""
from __future__ import annotations

import copy
import dataclasses
import threading
from collections import OrderedDict
from pathlib import Path

import numpy as np

from ...core import curves, gcode
from ..registry import Entry, Role
from ..ros_yaml import _read_file
from ..scenarios import resolve_part_program
from ..schema import COORDINATE_RANGE, MAX_PROGRAM_BYTES, MAX_PROGRAM_LINES, REQUIRED, SIZE_RANGE, Param, _printable

__all__ = ["CURVES", "TOOL_PATH_TYPES", "WINDOW", "program_warnings"]

CURVES = Role("curve", description="curve type")

#: the curve types that are part programs (tool paths planned block by block)
TOOL_PATH_TYPES = ("gcode", "toolpath")

WINDOW = Param("float", 0.0, "nonnegative", help="parameter half-width the exact contour error searches around the "
                                                 "reference (0: whole curve)", bounds=(0.0, 1e6))


def _size(name: str) -> Param:
    return Param("float", check="positive", help=f"size {name} [m]", bounds=SIZE_RANGE)


def _points(help: str, default=REQUIRED) -> Param:
    return Param("floats", default, help=help, bounds=COORDINATE_RANGE)


_CENTER = _points("centre [m]", [0.0, 0.0])
_SHAPE_H = Param("float", help="shape parameter h", bounds=(-1e3, 1e3))
_OMEGA = "angular rate [rad per unit of parameter]"


def _spline(s, context):
    coordinates = [s["x"], s["y"]] + ([s["z"]] if s["z"] is not None else [])
    if len({len(c) for c in coordinates}) != 1:
        raise ValueError("x, y (and z) must list the same number of points")
    return curves.SplineCurve(np.column_stack(coordinates), s["closed"])


#: the tool paths of the last few part programs read (by file, its size and time, and the options), so an
#: experiment's program is read and made a tool path once though its loading checks the curve and then
#: builds it; each caller gets its own shallow copy (attributes of its own, the segments and blocks shared)
KEPT_TOOL_PATHS = 2
_tool_paths = OrderedDict()
_tool_paths_lock = threading.Lock()


def _gcode(s, context):
    """A part program's tool path; ``file`` is read relative to the experiment file (then the scenario
    directory, then the working directory)."""
    if len(s["start"]) not in (2, 3):
        raise ValueError(f"start: expected 2 or 3 coordinates [m], got {len(s['start'])}")
    path = resolve_part_program(s["file"], context.where)
    if path is None:
        raise ValueError(f"file: cannot find the part program {s['file']!r} (relative paths are read from the "
                         "experiment file's directory)")
    try:
        stat = path.stat()
        key = (str(path.resolve()), stat.st_size, stat.st_mtime_ns, tuple(s["start"]), s["strict"],
               s["blend_tolerance"])
    except OSError:
        key = None
    with _tool_paths_lock:
        kept = _tool_paths.get(key) if key else None
    if kept is not None:
        return copy.copy(kept)
    tool_path = _read_tool_path(s, path)
    if key is not None:
        with _tool_paths_lock:
            _tool_paths[key] = tool_path
            while len(_tool_paths) > KEPT_TOOL_PATHS:
                _tool_paths.popitem(last=False)
    return copy.copy(tool_path)


def _read_tool_path(s, path: Path):
    """The tool path of the part program at ``path`` (ValueError naming the file where it cannot be made)."""
    raw = _read_file(path, _printable(path), MAX_PROGRAM_BYTES, "a part program is a text file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as error:
        raise ValueError(f"{path}: not a text file (not UTF-8 at byte {error.start})") from None
    lines = max(text.count("\n"), text.count("\r")) + (not text.endswith(("\n", "\r")))
    if lines > MAX_PROGRAM_LINES:          # before a block is read: a chord holds about 2.2 kB as a tool path
        raise ValueError(f"{path.name}: {lines} lines, over the {MAX_PROGRAM_LINES} a part program may have (split "
                         "it into several programs)")
    try:
        program = gcode.read_program(text.splitlines(), s["start"], s["strict"])
        del text, raw
        tool_path = curves.ToolPath.from_program(program, s["blend_tolerance"])
    except ValueError as error:
        raise ValueError(f"{path.name}: {error}") from None
    tool_path.program = dataclasses.replace(program, blocks=())     # its blocks are the path's; not its lines
    tool_path.source = str(path.resolve())
    return tool_path


def program_warnings(curve) -> list:
    """One line per kind of setup word the part program of ``curve`` read (none for other curves), naming
    the program file and the line."""
    program = getattr(curve, "program", None)
    if program is None:
        return []
    return [f"{Path(curve.source).name}: {warning}" for warning in program.warnings]


for _entry in (
    Entry("parabola", {"a": _size("a"), "h": _SHAPE_H}, lambda s, c: curves.Parabola(s["a"], s["h"])),
    Entry("circle", {"radius": Param("float", check="positive", help="radius [m]", bounds=SIZE_RANGE), "center": _CENTER},
          lambda s, c: curves.Circle(s["radius"], s["center"])),
    Entry("line", {"start": _points("start point [m]"), "end": _points("end point [m]")},
          lambda s, c: curves.Line(s["start"], s["end"])),
    Entry("ellipse", {"a": _size("a"), "b": _size("b"), "center": _CENTER},
          lambda s, c: curves.Ellipse(s["a"], s["b"], s["center"])),
    Entry("figure_eight", {"a": _size("a"), "b": _size("b"), "center": _CENTER},
          lambda s, c: curves.FigureEight(s["a"], s["b"], s["center"])),
    Entry("butterfly", {"scale": Param("float", check="positive", help="scale [m]", bounds=SIZE_RANGE),
                        "center": _CENTER},
          lambda s, c: curves.Butterfly(s["scale"], s["center"])),
    Entry("saddle", {"a": _size("a"), "b": _size("b"), "h": _SHAPE_H,
                     "omega": Param("float", 6.283185307179586, help=_OMEGA, bounds=(-1e4, 1e4))},
          lambda s, c: curves.Saddle(s["a"], s["b"], s["h"], s["omega"])),
    Entry("spline", {"x": _points("x coordinates of the points [m]"), "y": _points("y coordinates of the points [m]"),
                     "z": _points("z coordinates of the points [m]", None),
                     "closed": Param("bool", False, help="the spline closes on itself")},
          _spline),
    Entry("toolpath", {"start": _points("start point [m]"),
                       "moves": Param("strings", help="tool path moves (G1/G2/G3 words)")},
          lambda s, c: curves.ToolPath(s["start"], s["moves"])),
    Entry("gcode", {"file": Param("str", help="part program (RS274/NGC subset), absolute path"),
                    "start": _points("where the program starts [m]", [0.0, 0.0, 0.0]),
                    "blend_tolerance": Param("float", 0.0, "nonnegative", help="corner blending within this distance "
                                             "of the corner (as G64 P), 0: exact stop (G61) [m]", bounds=(0.0, 1e-2)),
                    "strict": Param("bool", False, help="refuse the part program's setup words (G40, G54, M3, T ...) "
                                                        "instead of reading and reporting them")},
          _gcode),
    Entry("helix", {"a": _size("a"), "b": _size("b"), "c": Param("float", help="pitch term c [m]", bounds=(-1e3, 1e3)),
                    "omega": Param("float", help=_OMEGA, bounds=(-1e4, 1e4)),
                    "length": Param("float", check="positive", help="parameter length", bounds=(1e-9, 1e6))},
          lambda s, c: curves.Helix(s["a"], s["b"], s["c"], s["omega"], s["length"])),
):
    _entry.params["contour_error_window"] = WINDOW
    CURVES.add(_entry)
