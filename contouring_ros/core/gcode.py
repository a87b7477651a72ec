"""Part programs: the RS274/NGC subset CNC part programs use, read into a program of blocks in metres.

The language is that of Kramer, Proctor and Messina, "The NIST RS274NGC Interpreter - Version 3", NISTIR
6556, 2000 (chapter 3, the input language; LinuxCNC's G-code reference follows it). Supported:

- G0 rapid, G1 line, G2 / G3 arc clockwise / counter-clockwise, in centre format I J K (offsets from the
  start point, always incremental) or radius format R (R > 0 the arc of at most a half turn, R < 0 the
  longer one); an arc whose end differs from its start along the plane's normal axis is a helix (the
  normal coordinate moves linearly with the angle);
- G17 / G18 / G19 plane selection XY / ZX / YZ: "clockwise" as seen from the positive end of the normal
  axis (Z, Y, X);
- G20 / G21 inch / millimetre units (millimetres until a program says otherwise);
- G90 / G91 absolute / incremental distance mode;
- F feed rate in units per minute, modal; N line numbers; comments in parentheses and after a semicolon;
  ``%`` on the first and last lines; M2 / M30 program end; X Y Z (up to 3 axes).

Every other word is refused with the line and the word; nothing is ignored silently.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

__all__ = ["Block", "Program", "ProgramError", "parse_program", "MM", "INCH"]

MM, INCH = 1e-3, 25.4e-3          # metres per unit
ARC_TOLERANCE = 2e-6              # m: an arc's end may lie this far off its circle (LinuxCNC's 0.002 mm)
_PLANES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}   # G17/18/19: first, second in-plane axis, normal axis
_CENTRE_WORDS = {0: "I", 1: "J", 2: "K"}
_WORD = re.compile(r"([A-Za-z])\s*([+-]?(?:\d+\.?\d*|\.\d+))")


MAX_NUMBER = 1e9          # a word's value at most this in size (a coordinate of 1e9 mm is already 1000 km)


class ProgramError(ValueError):
    """A part program that cannot be read; the message names the line (and the word)."""


@dataclass(frozen=True)
class Block:
    """One motion of a part program.

    Attributes
    ----------
    kind : str
        ``rapid`` (G0), ``line`` (G1) or ``arc`` (G2 / G3, helical when the normal coordinate changes).
    start, end : ndarray, shape (3,)
        Points [m].
    feed : float or None
        The block's programmed feed rate [m/s] (F / 60 in metres); None for rapids and for feed moves of a
        program without F words (the schedule's feedrate then applies).
    line : int
        Line number in the source (1-based), for messages.
    centre : ndarray, shape (3,) or None
        Arc centre [m] (its normal coordinate that of the start point).
    plane : tuple or None
        Arc plane as (first, second, normal) axis indices (G17: (0, 1, 2)).
    clockwise : bool
        G2 (True) or G3.
    """

    kind: str
    start: np.ndarray
    end: np.ndarray
    feed: float | None
    line: int
    centre: np.ndarray | None = None
    plane: tuple | None = None
    clockwise: bool = False


@dataclass(frozen=True)
class Program:
    """A parsed part program: its motion blocks and its dimension: 3 where it moves Z, arcs outside the XY
    plane or starts off z = 0, else 2."""

    blocks: list
    dimension: int
    has_feed_words: bool


def _strip_comments(text: str, number: int) -> str:
    out, depth = [], 0
    for char in text:
        if char == "(":
            if depth:
                raise ProgramError(f"line {number}: nested comment")
            depth = 1
        elif char == ")":
            if not depth:
                raise ProgramError(f"line {number}: ')' without '('")
            depth = 0
        elif char == ";" and not depth:
            break
        elif not depth:
            out.append(char)
    if depth:
        raise ProgramError(f"line {number}: comment not closed with ')'")
    return "".join(out)


def _words(text: str, number: int) -> list:
    """(letter, value) pairs of one line; anything that is not a word is refused."""
    words, at = [], 0
    body = text.strip()
    while at < len(body):
        if body[at].isspace():
            at += 1
            continue
        match = _WORD.match(body, at)
        if not match:
            raise ProgramError(f"line {number}: cannot read {body[at:].split()[0]!r} (expected words like X10.5)")
        value, word = float(match.group(2)), match.group(0).replace(" ", "")
        if not math.isfinite(value) or (abs(value) > MAX_NUMBER and match.group(1).upper() != "N"):
            shown = word if len(word) <= 24 else f"{word[:20]}... ({len(match.group(2))} characters)"
            raise ProgramError(f"line {number}: {shown}: the number is out of range (at most {MAX_NUMBER:g} "
                               "in size)")
        words.append((match.group(1).upper(), value, word))
        at = match.end()
    return words


def _code(value: float) -> int | None:
    return int(value) if value == int(value) else None


def parse_program(text: str, start=(0.0, 0.0, 0.0)) -> Program:
    """Read a part program (see the module docstring) starting at ``start`` [m].

    Raises
    ------
    ProgramError
        One line naming the source line and the word: an unsupported word, a move without a feed rate in a
        program with F words, an arc whose end is not on its circle, a word given twice ...
    """
    position = np.array(list(start) + [0.0] * (3 - len(start)), dtype=float)
    unit, absolute, plane, motion, feed = MM, True, _PLANES[17], None, None
    blocks, has_feed, ended = [], False, None
    moved_z = bool(position[2] != 0.0)         # a start off the XY plane keeps Z
    lines = text.splitlines()
    for number, raw in enumerate(lines, start=1):
        body = _strip_comments(raw, number).strip()
        if not body or (body == "%" and number in (1, len(lines))):     # % marks a program's start and end
            continue
        if ended is not None:
            raise ProgramError(f"line {number}: after the program end (M{ended} on an earlier line)")
        if body.startswith("/"):
            raise ProgramError(f"line {number}: block delete '/' is not supported")
        axes, centre, radius, seen = {}, {}, None, set()
        block_motion = None
        for letter, value, word in _words(body, number):
            if letter in "XYZIJKRFN" and letter in seen:
                raise ProgramError(f"line {number}: {letter} given twice")
            seen.add(letter)
            if letter == "N":
                continue
            if letter == "G":
                code = _code(value)
                if code in (0, 1, 2, 3):
                    if block_motion is not None:
                        raise ProgramError(f"line {number}: two motion words (G{block_motion} and {word})")
                    block_motion = code
                elif code in _PLANES:
                    plane = _PLANES[code]
                elif code in (20, 21):
                    unit = INCH if code == 20 else MM
                elif code in (90, 91):
                    absolute = code == 90
                else:
                    raise ProgramError(f"line {number}: unsupported word {word} (supported: G0 G1 G2 G3 G17 G18 "
                                       "G19 G20 G21 G90 G91)")
            elif letter == "M":
                code = _code(value)
                if code not in (2, 30):
                    raise ProgramError(f"line {number}: unsupported word {word} (supported: M2 M30)")
                ended = code
            elif letter in "XYZ":
                axes["XYZ".index(letter)] = value
            elif letter in "IJK":
                centre["IJK".index(letter)] = value
            elif letter == "R":
                radius = value
            elif letter == "F":
                if value <= 0.0:
                    raise ProgramError(f"line {number}: {word}: the feed rate must be positive")
                feed, has_feed = value, True
            else:
                raise ProgramError(f"line {number}: unsupported word {word}")
        if block_motion is not None:
            motion = block_motion
        if not axes:
            if centre or radius is not None:
                raise ProgramError(f"line {number}: arc words without an end point (X, Y or Z)")
            continue
        if motion is None:
            raise ProgramError(f"line {number}: coordinates without a motion mode (G0, G1, G2 or G3)")
        end = position.copy()
        for axis, value in axes.items():
            end[axis] = (value * unit) if absolute else position[axis] + value * unit
        if (2 in axes and end[2] != position[2]) or (motion in (2, 3) and plane != _PLANES[17]):
            moved_z = True                                  # an arc in the ZX or YZ plane moves Z
        block_feed = None if motion == 0 or feed is None else feed * unit / 60.0
        if motion in (0, 1):
            if centre or radius is not None:
                raise ProgramError(f"line {number}: {'I, J, K' if centre else 'R'} on a G{motion} line")
            if np.array_equal(end, position):
                continue                                    # a move to where the tool is: no motion
            blocks.append(Block("rapid" if motion == 0 else "line", position, end, block_feed, number))
        else:
            blocks.append(_arc(number, motion, plane, position, end, centre, radius, unit, block_feed))
        position = end
    if not blocks:
        raise ProgramError("the program has no motion")
    for block in blocks:                # F words given: every feed move needs one (none: the schedule's feed)
        if has_feed and block.kind != "rapid" and block.feed is None:
            code = "G1" if block.kind == "line" else "G2" if block.clockwise else "G3"
            raise ProgramError(f"line {block.line}: {code} before any feed rate (F)")
    return Program(blocks, 3 if moved_z else 2, has_feed)


def _arc(number, motion, plane, start, end, centre_words, radius, unit, feed) -> Block:
    """A G2 / G3 block: centre from I J K (offsets from the start) or from R (on the chord's perpendicular
    bisector, at sqrt(R^2 - (chord / 2)^2) from its middle: left of the chord for a short counter-clockwise
    arc, right for a short clockwise one, the other side for R < 0)."""
    first, second, normal = plane
    name = f"G{motion}"
    allowed = {first, second}
    extra = set(centre_words) - allowed
    if extra:
        raise ProgramError(f"line {number}: {_CENTRE_WORDS[min(extra)]} is not a centre offset in the "
                           f"{'XYZ'[first]}{'XYZ'[second]} plane")
    a = np.array([start[first], start[second]])
    b = np.array([end[first], end[second]])
    ccw = motion == 3
    if radius is not None:
        if centre_words:
            raise ProgramError(f"line {number}: {name} with both R and a centre offset")
        chord = b - a
        half = float(np.linalg.norm(chord)) / 2.0
        r = abs(radius) * unit
        if half == 0.0:
            raise ProgramError(f"line {number}: {name} with R needs an end point other than its start in the plane")
        if r < half - ARC_TOLERANCE:
            raise ProgramError(f"line {number}: {name}: R{radius:g} is shorter than half the chord "
                               f"({half / unit:g})")
        offset = math.sqrt(max(r * r - half * half, 0.0))
        left = np.array([-chord[1], chord[0]]) / (2.0 * half)
        side = (1.0 if ccw else -1.0) * (1.0 if radius > 0 else -1.0)
        c = (a + b) / 2.0 + side * offset * left
    else:
        if not centre_words:
            raise ProgramError(f"line {number}: {name} needs a centre offset ({_CENTRE_WORDS[first]}, "
                               f"{_CENTRE_WORDS[second]}) or R")
        c = a + np.array([centre_words.get(first, 0.0), centre_words.get(second, 0.0)]) * unit
        r0, r1 = float(np.linalg.norm(a - c)), float(np.linalg.norm(b - c))
        if r0 == 0.0:
            raise ProgramError(f"line {number}: {name}: a zero radius")
        if abs(r1 - r0) > ARC_TOLERANCE:
            raise ProgramError(f"line {number}: {name}: the end point is {abs(r1 - r0) / unit:.4g} off the arc's "
                               f"circle (radius {r0 / unit:.6g} at the start, {r1 / unit:.6g} at the end)")
    centre = start.copy()
    centre[first], centre[second] = c
    return Block("arc", start, end, feed, number, centre, plane, not ccw)
