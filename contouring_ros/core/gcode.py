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
  ``%`` on the first and last lines; M2 / M30 program end; X Y Z (up to 3 axes);
- path control (LinuxCNC's G-code reference, "G61, G61.1 Exact Path Mode", "G64 Path Blending", "G9",
  "G4 Dwell"): G61 and G61.1 exact stop at every corner (modal), G9 exact stop at the end of its own block,
  G64 P p [Q q] blending within p of each corner (modal; G64 without P: within :data:`JUNCTION_DEVIATION`),
  Q its naive CAM tolerance: consecutive G1 blocks whose end points lie within q of one straight line are
  merged into one (:func:`merge_collinear`), G4 P seconds dwell (the motion stops first).
  A program that says none of them takes the experiment's ``blend_tolerance`` (0: exact stop, as G61);
- setup words every post-processor writes at the top of a program (:data:`SETUP_WORDS`): G40, G49, G54-G59
  (zero work offsets: the program's coordinates are the machine's), G80, G94, M3 / M4 / M5 with S, T with M6,
  M7 / M8 / M9 and O numbers are read and have no effect on the path; they are reported in one line naming
  each word once and the lines they span (``Program.warnings``). ``strict=True`` refuses them instead.

Motion the project cannot do (cutter compensation G41 / G42, tool length offsets G43, inverse-time and
per-revolution feed G93 / G95, canned cycles G73 G76 G81-G89) is refused in either mode, and so is every
other word, each in one line naming the line and the word; nothing is ignored silently.
"""
from __future__ import annotations

import math
import re
from array import array
from dataclasses import dataclass, field, replace

import numpy as np


__all__ = ["Block", "LineRun", "Program", "ProgramError", "ProgramReader", "SourceBlocks", "parse_program", "read_program",
           "merge_collinear", "MM", "INCH", "JUNCTION_DEVIATION", "SETUP_WORDS", "SOURCE_CODES", "MAX_MERGED"]

MM, INCH = 1e-3, 25.4e-3          # metres per unit
ARC_TOLERANCE = 2e-6              # m: an arc's end may lie this far off its circle (LinuxCNC's 0.002 mm)
_PLANES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}   # G17/18/19: first, second in-plane axis, normal axis
_CENTRE_WORDS = {0: "I", 1: "J", 2: "K"}
JUNCTION_DEVIATION = 1e-5         # m: G64 without P blends within this (grbl's default junction deviation)
#: the setup words read and reported (strict mode refuses them): the word's kind and what reading it means
SETUP_WORDS = {
    "G40": ("cutter compensation off", "the programmed path is run"),
    "G49": ("tool length offset off", "the programmed path is run"),
    "G54": ("work offsets", "zero offsets: the program's coordinates are the machine's"),
    "G80": ("canned cycle off", "no cycle was on"),
    "G94": ("feed per minute", "F is read per minute, the only feed mode"),
    "M3": ("spindle", "no spindle is simulated"),
    "T": ("tool change", "no tool is simulated"),
    "M8": ("coolant", "no coolant is simulated"),
    "O": ("program numbers", "a label"),
}
_SETUP_KIND = {**{f"G{c}": "G54" for c in ("54", "55", "56", "57", "58", "59", "59.1", "59.2", "59.3")},
               "G40": "G40", "G49": "G49", "G80": "G80", "G94": "G94", "M3": "M3", "M4": "M3", "M5": "M3",
               "S": "M3", "T": "T", "M6": "T", "M7": "M8", "M8": "M8", "M9": "M8", "O": "O"}
#: motion the project cannot do: refused in either mode
_REFUSED = {**{f"G{c}": "cutter radius compensation" for c in ("41", "41.1", "42", "42.1")},
            **{f"G{c}": "tool length offsets" for c in ("43", "43.1", "43.2")},
            "G93": "inverse-time feed", "G95": "feed per revolution",
            **{f"G{c}": "canned cycles" for c in ("73", "76", "81", "82", "83", "84", "85", "86", "87", "88",
                                                     "89")}}
_WORD = re.compile(r"([A-Za-z])\s*([+-]?(?:\d+\.?\d*|\.\d+))")
_WORDS = re.compile(r"(?:\s*[A-Za-z]\s*[+-]?(?:\d+(?:\.\d*)?|\.\d+))*\s*")      # a line of words alone
_NUMBER = r"[+-]?(?:\d+\.?\d*|\.\d+)"
#: a plain G1 line: an optional N number, an optional G1 (G01 ...), then X, Y, Z in that order (each optional),
#: nothing else (no comment, no other word): what :meth:`ProgramReader.blocks` reads as a :class:`LineRun`
_PLAIN_G1 = re.compile(rf"\s*(?:[Nn]\s*(\d+)\s*)?([Gg]\s*0*1(?![\d.])\s*)?(?:[Xx]\s*({_NUMBER})\s*)?"
                       rf"(?:[Yy]\s*({_NUMBER})\s*)?(?:[Zz]\s*({_NUMBER})\s*)?")


MAX_NUMBER = 1e9          # a word's value at most this in size (a coordinate of 1e9 mm is already 1000 km)


class ProgramError(ValueError):
    """A part program that cannot be read; the message names the line (and the word)."""


@dataclass(frozen=True, slots=True)
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
    tolerance : float or None
        How far [m] the path may leave the corner at the block's end: G64 P (> 0), 0 for an exact stop (G61,
        G61.1, G9); None where the program says neither (the experiment's ``blend_tolerance``).
    dwell : float
        [s] G4 dwell after the block.
    number : int or None
        Its N number, where the line gives one.
    merge_tolerance : float
        [m] G64 Q in force on a G1 block (0: none): :func:`merge_collinear` may merge it with its neighbours.
    merged : int
        How many G1 blocks of the program it stands for (1, or more where they were merged; ``line`` and
        ``number`` are the first's).
    """

    kind: str
    start: np.ndarray
    end: np.ndarray
    feed: float | None
    line: int
    centre: np.ndarray | None = None
    plane: tuple | None = None
    clockwise: bool = False
    tolerance: float | None = None
    dwell: float = 0.0
    number: int | None = None
    merge_tolerance: float = 0.0
    merged: int = 1


#: the G word of a block of the source (:class:`SourceBlocks`)
SOURCE_CODES = ("G0", "G1", "G2", "G3")


class SourceBlocks:
    """What the results per block say of each motion block of a program: its source line, N number and G
    word, as arrays (a long program costs 17 bytes a block), in program order."""

    def __init__(self, blocks=()):
        lines, numbers, codes = array("q"), array("q"), array("b")
        for block in blocks:
            lines.append(block.line)
            numbers.append(-1 if block.number is None else block.number)
            codes.append(SOURCE_CODES.index("G0" if block.kind == "rapid" else _code_of(block)))
        self.lines = np.array(lines, dtype=np.int64)
        self._numbers, self._codes = np.array(numbers, dtype=np.int64), np.array(codes, dtype=np.int8)

    def _index(self, line: int) -> int | None:
        i = int(np.searchsorted(self.lines, line))
        return i if i < len(self.lines) and self.lines[i] == line else None

    def number(self, line: int) -> int | None:
        """The N number of the block at source ``line`` (None without one, or without a block there)."""
        i = self._index(line)
        return None if i is None or self._numbers[i] < 0 else int(self._numbers[i])

    def codes(self, lines) -> list:
        """The G word of the block at each source line (None where none is)."""
        lines = np.asarray(lines, dtype=np.int64)
        i = np.clip(np.searchsorted(self.lines, lines), 0, max(len(self.lines) - 1, 0))
        found = (self.lines[i] == lines) if len(self.lines) else np.zeros(len(lines), dtype=bool)
        return [SOURCE_CODES[c] if f else None for c, f in zip(self._codes[i].tolist(), found.tolist())]


@dataclass(frozen=True)
class Program:
    """A parsed part program: its motion blocks and its dimension: 3 where it moves Z, arcs outside the XY
    plane or starts off z = 0, else 2; ``warnings``: one line naming the setup words read (none without);
    ``dwell``: [s] of
    G4 before the first motion; ``unit``: [m] per program unit (MM or INCH) of its first motion, in which
    results per block are reported; ``sources``: its blocks' lines, N numbers and G words
    (:class:`SourceBlocks`). ``blocks`` is a list (:func:`parse_program`) or an iterable that reads the
    program again each time (:func:`read_program`)."""

    blocks: list
    dimension: int
    has_feed_words: bool
    warnings: tuple = ()
    dwell: float = 0.0
    unit: float = MM
    sources: SourceBlocks | None = None


def _strip_comments(text: str, number: int) -> str:
    if "(" not in text and ")" not in text and ";" not in text:
        return text
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
    words = []
    body = text.strip()
    for match in _WORD.finditer(body) if _WORDS.fullmatch(body) else _word_by_word(body, number):
        value, word = float(match.group(2)), match.group(0).replace(" ", "")
        if not math.isfinite(value) or (abs(value) > MAX_NUMBER and match.group(1).upper() != "N"):
            shown = word if len(word) <= 24 else f"{word[:20]}... ({len(match.group(2))} characters)"
            raise ProgramError(f"line {number}: {shown}: the number is out of range (at most {MAX_NUMBER:g} "
                               "in size)")
        words.append((match.group(1).upper(), value, word))
    return words


def _word_by_word(body: str, number: int):
    """The words of a line that is not words alone, one at a time up to the first thing that is not a word,
    which is refused there (a number out of range before it is refused first)."""
    at = 0
    while at < len(body):
        if body[at].isspace():
            at += 1
            continue
        match = _WORD.match(body, at)
        if not match:
            raise ProgramError(f"line {number}: cannot read {body[at:].split()[0]!r} (expected words like X10.5)")
        yield match
        at = match.end()


def _code(value: float) -> int | None:
    return int(value) if value == int(value) else None


def _name(letter: str, value: float) -> str:
    """A G or M word's canonical name: G01 -> G1, G61.10 -> G61.1."""
    return f"{letter}{value:.4f}".rstrip("0").rstrip(".")


@dataclass
class _Modal:
    """The modal state of a program as far as it has been read (NISTIR 6556's modal groups): where the
    tool is [m], the units [m per program unit], the distance mode, the plane, the motion mode, the feed
    rate (program units per minute; None before the first F word) and the path control: ``tolerance``
    None (the experiment's), 0 (G61) or G64 P [m]; ``naive`` G64 Q [m] (0: no merging)."""

    position: np.ndarray
    unit: float = MM
    absolute: bool = True
    plane: tuple = _PLANES[17]
    motion: int | None = None
    feed: float | None = None
    tolerance: float | None = None
    naive: float = 0.0


@dataclass
class _Line:
    """What one line of a program says for itself: its words as written (letter -> (value, word)), the axis
    words (axis index -> value), the centre offsets I J K (axis index -> value), R, and its motion (G0 ..
    G3), G9, G4, G64 and M2 / M30 (``end``)."""

    number: int
    words: dict = field(default_factory=dict)
    axes: dict = field(default_factory=dict)
    centre: dict = field(default_factory=dict)
    radius: float | None = None
    motion: int | None = None
    exact_once: bool = False
    dwell: bool = False
    blend: bool = False
    end: int | None = None


def parse_program(text: str, start=(0.0, 0.0, 0.0), strict: bool = False) -> Program:
    """Read a part program (see the module docstring) starting at ``start`` [m].

    ``strict``: refuse the setup words (:data:`SETUP_WORDS`) instead of reading and reporting them.

    Raises
    ------
    ProgramError
        One line naming the source line and the word: an unsupported word, a move without a feed rate in a
        program with F words, an arc whose end is not on its circle, a word given twice ...
    """
    lines = text.splitlines()
    reader = ProgramReader(start, strict)
    blocks = list(_check_feeds(reader.blocks(lines, last=len(lines)), reader))
    return Program(list(merge_collinear(blocks)), reader.dimension, reader.has_feed, reader.warnings,
                   reader.first_dwell, reader.unit, SourceBlocks(blocks))


def read_program(lines: list, start=(0.0, 0.0, 0.0), strict: bool = False) -> Program:
    """:func:`parse_program` of a program's ``lines`` that keeps no block: the program is read once to learn
    what it states as a whole and to check it, and its ``blocks`` read it again each time they are iterated
    (the same blocks, merged as :func:`merge_collinear` merges them). A program of a million blocks costs its
    lines and :class:`SourceBlocks`, not a million :class:`Block` objects."""
    reader = ProgramReader(start, strict)
    sources = SourceBlocks(_check_feeds(reader.blocks(lines, last=len(lines)), reader))
    return Program(_Reread(lines, start, strict), reader.dimension, reader.has_feed, reader.warnings,
                   reader.first_dwell, reader.unit, sources)


def _check_feeds(blocks, reader: ProgramReader):
    """``blocks`` (a generator of ``reader``'s) passed on; where the program has F words, the first feed move
    before any of them is refused once all are read (a program without F words takes the schedule's feed)."""
    feedless = None
    for block in blocks:
        if feedless is None and block.kind != "rapid" and block.feed is None:
            feedless = block
        yield block
    if reader.has_feed and feedless is not None:
        raise ProgramError(f"line {feedless.line}: {_code_of(feedless)} before any feed rate (F)")


class _Reread:
    """A program's blocks as :func:`read_program` gives them: each iteration reads its lines again."""

    def __init__(self, lines, start, strict: bool):
        self.lines, self.start, self.strict = lines, start, strict

    def __iter__(self):
        return merge_collinear(ProgramReader(self.start, self.strict).blocks(self.lines, last=len(self.lines)))


def _code_of(block: Block) -> str:
    return "G1" if block.kind == "line" else "G2" if block.clockwise else "G3"


class LineRun:
    """Consecutive G1 blocks with one feed [m/s] and path tolerance (G64 P [m]; None: the experiment's), no
    dwell, no G64 Q: ``points`` (n + 1, 3) [m] the start and each block's end, ``lines`` their source lines,
    ``numbers`` their N numbers (-1: none). ``kind`` "run" (no block kind: nothing merges with it)."""

    kind = "run"
    merge_tolerance = 0.0
    dwell = 0.0

    def __init__(self, points: np.ndarray, lines: np.ndarray, numbers: np.ndarray, feed: float, tolerance):
        self.points, self.lines, self.numbers, self.feed, self.tolerance = points, lines, numbers, feed, tolerance

    def __len__(self) -> int:
        return len(self.lines)

    def blocks(self) -> list:
        """The run's :class:`~contouring_ros.core.gcode.Block` objects."""
        points = list(self.points)
        return [Block("line", points[i], points[i + 1], self.feed, int(line), tolerance=self.tolerance,
                      number=None if number < 0 else int(number))
                for i, (line, number) in enumerate(zip(self.lines.tolist(), self.numbers.tolist()))]


class ProgramReader:
    """Reads a part program line by line into its motion blocks (:meth:`blocks`, a generator: a program of
    any length is read in constant memory), keeping what :class:`Program` states about the whole program as
    far as it has been read: ``dimension``, ``has_feed``, ``warnings``, ``first_dwell``, ``unit``."""

    def __init__(self, start=(0.0, 0.0, 0.0), strict: bool = False):
        self.start, self.strict = start, strict
        self.has_feed, self.first_dwell, self._seen, self._first_unit = False, 0.0, {}, None
        self._moved_z = False

    @property
    def dimension(self) -> int:
        return 3 if self._moved_z else 2

    @property
    def warnings(self) -> tuple:
        return _setup_summary(self._seen)

    @property
    def unit(self) -> float:
        return self._first_unit or MM

    def blocks(self, lines, last: int | None = None, runs: int = 0):
        """The motion blocks of ``lines`` (an iterable of the program's lines), each yielded once the next
        line that could change it (a G4 dwell adds to the block before it) has been read. ``last``: the number
        of lines, where known (a ``%`` on it ends the program); None (a stream): a ``%`` on any line after the
        first ends it, and a feed move before the first F word is refused when an F word follows (the move
        has already run at the schedule's feed).

        ``runs`` > 0: consecutive plain G1 lines (:data:`_PLAIN_G1`: axis words alone, with an optional N number
        and G1, in absolute mode, once a feed is set and where no G64 Q merges them) are read by one regular
        expression each and handed on as a :class:`LineRun` of up to
        ``runs`` blocks (what a run adds to the read-ahead), their last one held back as a block (a G4 may add to it): the same blocks
        as ``LineRun.blocks`` gives them (tested), without the general reader's cost per line."""
        modal = _Modal(np.array(list(self.start) + [0.0] * (3 - len(self.start)), dtype=float))
        pending, ended, feedless, moved = None, None, None, False
        self._moved_z = bool(modal.position[2] != 0.0)     # a start off the XY plane keeps Z
        number = 0
        run = _PlainRun()
        for number, raw in enumerate(lines, start=1):
            if runs:
                if ended is None and self._plain(raw, number, modal, run):
                    if pending is not None and run.lines:
                        yield pending
                        pending = None
                    if len(run.lines) > runs:
                        yield run.take()
                    continue
                if run.points:
                    yield from run.end(modal)
                    if run.last is not None:
                        pending, moved = run.last, True
            body = _strip_comments(raw, number).strip()
            if not body:
                continue
            if body == "%" and (number == 1 or number == last or (last is None and ended != "%")):
                if number != 1 and last is None:
                    ended = "%"                     # a stream's closing %
                continue                            # % marks a program's start and end
            if ended is not None:
                mark = "%" if ended == "%" else f"M{ended}"
                raise ProgramError(f"line {number}: after the program end ({mark} on an earlier line)")
            if body.startswith("/"):
                raise ProgramError(f"line {number}: block delete '/' is not supported")
            line = self._read_words(body, number, modal, feedless if last is None else None)
            ended = line.end
            seconds = _path_control(line, modal)
            if seconds is not None:
                if pending is not None:
                    pending = replace(pending, dwell=pending.dwell + seconds)
                elif not moved:
                    self.first_dwell += seconds
            if line.motion is not None:
                modal.motion = line.motion
            block = self._motion(line, modal)
            if block is None:
                continue
            if block.kind != "rapid" and block.feed is None and feedless is None:
                feedless = block
            if pending is not None:
                yield pending
            pending, moved = block, True
        if run.points:
            yield from run.end(modal)
            if run.last is not None:
                pending = run.last
        if pending is None:
            raise ProgramError("the program has no motion")
        yield pending

    def _plain(self, raw: str, number: int, modal: _Modal, run: "_PlainRun") -> bool:
        """Read line ``number`` into ``run`` where it is a plain G1 line the ``modal`` state lets a
        :class:`LineRun` hold (see :meth:`blocks`): its end point as the general reader computes it (a move to
        where the tool is adds nothing); False, reading nothing, where it is not."""
        match = _PLAIN_G1.fullmatch(raw)
        if match is None:
            return False
        label, g1, *axes = match.groups()
        if axes == [None, None, None] or not modal.absolute or modal.feed is None or \
                (modal.naive and modal.tolerance) or (g1 is None and modal.motion != 1):
            return False
        values = [None if a is None else float(a) for a in axes]
        if any(v is not None and not abs(v) <= MAX_NUMBER for v in values):
            return False                                     # refused by the general reader, in its words
        if g1 is not None:
            modal.motion = 1
        if self._first_unit is None:
            self._first_unit = modal.unit
        if not run.points:
            run.begin(modal)
        here, unit = run.points[-1], modal.unit
        end = tuple([h if v is None else v * unit for h, v in zip(here, values)])
        if end == here:
            return True                                      # a move to where the tool is: no motion
        if values[2] is not None and end[2] != here[2]:
            self._moved_z = True
        run.points.append(end)
        run.lines.append(number)
        run.numbers.append(-1 if label is None else int(float(label)))
        return True

    def _read_words(self, body: str, number: int, modal: _Modal, feedless: Block | None) -> _Line:
        """The words of line ``number`` (its text ``body``): the modal ones (plane, units, distance mode, G61,
        F) change ``modal`` as they are read, in their order on the line; the setup words are reported (refused
        when strict). ``feedless``: a feed move a stream has already run before any F word, which an F word
        refuses."""
        line = _Line(number)
        for letter, value, word in _words(body, number):
            if letter in "XYZIJKRFNPQSTO" and letter in line.words:
                raise ProgramError(f"line {number}: {letter} given twice")
            line.words[letter] = (value, word)
            name = _name(letter, value) if letter in "GM" else letter
            if name in _REFUSED:
                raise ProgramError(f"line {number}: unsupported word {word} ({_REFUSED[name]}: the project runs "
                                   "the programmed path as it is, in either mode)")
            if name in _SETUP_KIND:
                kind = _SETUP_KIND[name]
                meaning = SETUP_WORDS[kind][0]
                if self.strict:
                    raise ProgramError(f"line {number}: {word} ({meaning}) is a setup word; strict: true "
                                       "refuses them (leave strict out to read and report them)")
                self._seen.setdefault(name, (word, number))
                continue
            if letter in "NPQ":
                continue
            if letter == "G":
                _g_word(line, modal, value, name, word)
            elif letter == "M":
                code = _code(value)
                if code not in (2, 30):
                    raise ProgramError(f"line {number}: unsupported word {word} (supported: M2 M30 and the "
                                       "setup words M3 M4 M5 M6 M7 M8 M9)")
                line.end = code
            elif letter in "XYZ":
                line.axes["XYZ".index(letter)] = value
            elif letter in "IJK":
                line.centre["IJK".index(letter)] = value
            elif letter == "R":
                line.radius = value
            elif letter == "F":
                if value <= 0.0:
                    raise ProgramError(f"line {number}: {word}: the feed rate must be positive")
                if feedless is not None:
                    raise ProgramError(f"line {feedless.line}: {_code_of(feedless)} before any feed rate (F)")
                modal.feed, self.has_feed = value, True
            else:
                raise ProgramError(f"line {number}: unsupported word {word}")
        return line

    def _motion(self, line: _Line, modal: _Modal) -> Block | None:
        """The motion block of ``line`` in the ``modal`` state, which then moves to its end; None for a line
        without coordinates or a move to where the tool is."""
        number, motion, position, unit = line.number, modal.motion, modal.position, modal.unit
        centre, radius = line.centre, line.radius
        if not line.axes:
            if centre or radius is not None:
                raise ProgramError(f"line {number}: arc words without an end point (X, Y or Z)")
            return None
        if motion is None:
            raise ProgramError(f"line {number}: coordinates without a motion mode (G0, G1, G2 or G3)")
        end = position.copy()
        for axis, value in line.axes.items():
            end[axis] = (value * unit) if modal.absolute else position[axis] + value * unit
        if (2 in line.axes and end[2] != position[2]) or (motion in (2, 3) and modal.plane != _PLANES[17]):
            self._moved_z = True                            # an arc in the ZX or YZ plane moves Z
        block_feed = None if motion == 0 or modal.feed is None else modal.feed * unit / 60.0
        block_tolerance = 0.0 if line.exact_once else modal.tolerance
        label = _code(line.words["N"][0]) if "N" in line.words else None
        if self._first_unit is None:
            self._first_unit = unit
        if motion in (0, 1):
            if centre or radius is not None:
                raise ProgramError(f"line {number}: {'I, J, K' if centre else 'R'} on a G{motion} line")
            if end.tolist() == position.tolist():
                return None                                 # a move to where the tool is: no motion
            block = Block("rapid" if motion == 0 else "line", position, end, block_feed, number,
                          tolerance=block_tolerance, number=label,
                          merge_tolerance=modal.naive if motion == 1 and block_tolerance else 0.0)
        else:
            block = replace(_arc(number, motion, modal.plane, position, end, centre, radius, unit, block_feed),
                            tolerance=block_tolerance, number=label)
        modal.position = end
        return block


class _PlainRun:
    """The plain G1 lines :meth:`ProgramReader.blocks` has read and not yet handed on: the point the run
    starts from and each line's end point, source line and N number (-1: none), in the modal state they were
    read in (a run ends at the first line that is not plain, so the state holds across it)."""

    def __init__(self):
        self.points, self.lines, self.numbers = [], [], []

    def begin(self, modal: _Modal) -> None:
        self.points.append(tuple(modal.position.tolist()))
        self.feed, self.tolerance = modal.feed * modal.unit / 60.0, modal.tolerance

    def take(self) -> LineRun:
        """The run's blocks but the last as a :class:`LineRun`; the last starts the run on."""
        run = LineRun(np.array(self.points[:-1]), np.array(self.lines[:-1], dtype=np.int64),
                      np.array(self.numbers[:-1], dtype=np.int64), self.feed, self.tolerance)
        del self.points[:-2], self.lines[:-1], self.numbers[:-1]
        return run

    def end(self, modal: _Modal):
        """End the run: its blocks but the last as a :class:`LineRun` (yielded, where there are any) and the
        last as a :class:`Block` in ``last`` (None where the run moved nothing), the modal position moved to
        where the run ends."""
        self.last = None
        if len(self.lines) > 1:
            yield self.take()
        if self.lines:
            label = self.numbers[-1]
            self.last = Block("line", np.array(self.points[-2]), np.array(self.points[-1]), self.feed,
                              self.lines[-1], tolerance=self.tolerance, number=None if label < 0 else label)
            modal.position = self.last.end
        self.points, self.lines, self.numbers = [], [], []


def _g_word(line: _Line, modal: _Modal, value: float, name: str, word: str) -> None:
    """Read the G word ``word`` (its value, its canonical name) of ``line``: the modal groups (plane, units,
    distance mode, G61) change ``modal``; a motion, G9, G4 and G64 are the line's."""
    code = _code(value)
    if code in (0, 1, 2, 3):
        if line.motion is not None:
            raise ProgramError(f"line {line.number}: two motion words (G{line.motion} and {word})")
        line.motion = code
    elif code in _PLANES:
        modal.plane = _PLANES[code]
    elif code in (20, 21):
        modal.unit = INCH if code == 20 else MM
    elif code in (90, 91):
        modal.absolute = code == 90
    elif name in ("G61", "G61.1"):
        modal.tolerance, modal.naive = 0.0, 0.0
    elif code == 64:
        line.blend = True
    elif code == 9:
        line.exact_once = True
    elif code == 4:
        line.dwell = True
    else:
        raise ProgramError(f"line {line.number}: unsupported word {word} (supported: G0 G1 G2 G3 G4 G9 "
                           "G17 G18 G19 G20 G21 G61 G61.1 G64 G90 G91 and the setup words G40 G49 "
                           "G54-G59 G80 G94)")


def _path_control(line: _Line, modal: _Modal) -> float | None:
    """Check the P and Q words of ``line`` against its G4 / G64, take a G64's blending (P) and naive CAM (Q)
    tolerances into ``modal``, and return a G4's dwell [s] (None without G4)."""
    number, words = line.number, line.words
    if line.dwell and line.blend:
        raise ProgramError(f"line {number}: G4 and G64 on one line (both take P)")
    if "P" in words and not (line.dwell or line.blend):
        raise ProgramError(f"line {number}: {words['P'][1]} without G4 or G64")
    if "Q" in words and not line.blend:
        raise ProgramError(f"line {number}: {words['Q'][1]} without G64")
    if line.blend:
        p = words.get("P", (None,))[0]
        if p is not None and p < 0.0:
            raise ProgramError(f"line {number}: {words['P'][1]}: the blending tolerance must not be "
                               "negative")
        modal.tolerance = JUNCTION_DEVIATION if p is None else p * modal.unit
        q = words.get("Q", (0.0,))[0]
        if q < 0.0:
            raise ProgramError(f"line {number}: {words['Q'][1]}: the naive CAM tolerance must not be "
                               "negative")
        modal.naive = q * modal.unit
    if not line.dwell:
        return None
    if "P" not in words:
        raise ProgramError(f"line {number}: G4 needs its dwell P (seconds)")
    seconds = words["P"][0]
    if not 0.0 <= seconds <= 3600.0:
        raise ProgramError(f"line {number}: {words['P'][1]}: a dwell of 0 to 3600 s")
    if line.axes:
        raise ProgramError(f"line {number}: G4 with a motion on one line (give the dwell its own line)")
    return seconds


#: at most this many G1 blocks are merged into one (LinuxCNC's emccanon.cc: linkable, over 100 chained points)
MAX_MERGED = 100


def merge_collinear(blocks):
    """``blocks`` with runs of consecutive G1 blocks under G64 Q q merged into one line, as LinuxCNC's canonical
    layer does (src/emc/task/emccanon.cc: see_segment, linkable, flush_segments): a G1 block joins the run
    when its feed, path tolerance and q are the run's, no exact stop or dwell ends the run before it, the
    run has fewer than :data:`MAX_MERGED` blocks, and every end point of the run, its own included, lies
    within q of the straight line from the run's start to its end (the distance to that segment, the
    projection clamped to it). The merged line runs from the first block's start to the last's end, with the
    first's line and N number, the last's tolerance and dwell. Anything else (G0, arcs, a feed change) ends a
    run. A generator over any iterable of blocks: it holds at most one run (:data:`MAX_MERGED` blocks)."""
    run = []

    def merged():
        last = run[-1]
        return replace(run[0], end=last.end, tolerance=last.tolerance, dwell=last.dwell, merged=len(run)) \
            if len(run) > 1 else last
    for block in blocks:
        if run and _linkable(run, block):
            run.append(block)
            continue
        if run:
            yield merged()
            run.clear()
        if block.kind == "line" and block.merge_tolerance > 0.0:
            run.append(block)
        else:
            yield block
    if run:
        yield merged()


def _linkable(run: list, block: Block) -> bool:
    first, last = run[0], run[-1]
    if block.kind != "line" or len(run) >= MAX_MERGED or last.dwell > 0.0 or not last.tolerance or \
            (block.feed, block.tolerance, block.merge_tolerance) != (first.feed, first.tolerance,
                                                                    first.merge_tolerance):
        return False
    start, chord = first.start, block.end - first.start
    squared = float(np.dot(chord, chord))
    if squared == 0.0:
        return False
    points = np.array([b.end for b in run] + [block.end])
    along = np.clip((points - start) @ chord / squared, 0.0, 1.0)
    distance = np.linalg.norm(points - (start + along[:, None] * chord), axis=1)
    return bool(np.all(distance <= block.merge_tolerance))


def _setup_summary(seen: dict) -> tuple:
    """One line naming each setup word read (name -> (the word as first written, its line)), in the order
    first read, with the lines they span: a CAM post-processor's header is one line, not one per kind."""
    if not seen:
        return ()
    lines = sorted({line for _, line in seen.values()})
    where = f"line {lines[0]}" if len(lines) == 1 else f"lines {lines[0]}-{lines[-1]}"
    return (f"{where}: setup words {' '.join(word for word, _ in seen.values())} read, with no effect on the "
            "path (zero work offsets; no spindle, tool or coolant is simulated; strict: true refuses them)",)


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
