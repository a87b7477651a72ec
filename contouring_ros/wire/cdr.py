"""A minimal CDR codec for the graph's three message types, so nodes publish and take raw bytes.

rclpy's own (de)serialisation builds Python message objects on every hop; the lockstep path only needs a
few float arrays and the header stamp, so the nodes encode and decode the wire format directly
(XCDR1, little endian, as rmw_fastrtps sends it: a 4-byte encapsulation header, then each field aligned
to its size relative to the end of that header). The tests check the bytes against rclpy's serializer.

Decoded messages are small objects with the field names of the ROS messages they stand for, so the
conversions in :mod:`contouring_ros.wire.graph` work on them, on rclpy messages and on decoded bag messages alike.

A topic's messages keep their layout (same names, same array lengths), so both directions cache it: an
encoder fills a cached template with the stamp and the values; a decoder that finds every byte but the
stamp and the float64 values equal to a message it parsed in full reads the values at that message's
offsets with one precompiled struct, and parses anything else in full.
"""
from __future__ import annotations

import copy
import struct
from dataclasses import dataclass, field

__all__ = ["Stamp", "Header", "JointStateData", "TrajectoryPointData", "JointTrajectoryData", "stamp_ns",
           "encode_joint_state", "decode_joint_state", "encode_joint_trajectory", "decode_joint_trajectory",
           "preview_points",
           "encode_clock", "array_layout", "values_struct"]

_ENCAPSULATION = b"\x00\x01\x00\x00"   # CDR, little endian
_STAMP = struct.Struct("<iI")
_U32 = struct.Struct("<I")


@dataclass
class Stamp:
    sec: int
    nanosec: int


@dataclass
class Header:
    stamp: Stamp
    frame_id: str = ""


@dataclass
class JointStateData:
    header: Header
    name: list
    position: tuple
    velocity: tuple
    effort: tuple


@dataclass
class TrajectoryPointData:
    positions: tuple
    velocities: tuple
    accelerations: tuple
    effort: tuple = ()
    time_from_start: Stamp = field(default_factory=lambda: Stamp(0, 0))


@dataclass
class JointTrajectoryData:
    header: Header
    joint_names: list
    points: list


def stamp_ns(data: bytes) -> int:
    """The header stamp (or the Clock time) of a serialised message, in nanoseconds."""
    sec, nanosec = _STAMP.unpack_from(data, 4)
    return sec * 1_000_000_000 + nanosec


class _Writer:
    def __init__(self):
        self.parts = [_ENCAPSULATION]
        self.size = 0   # bytes after the encapsulation header
        self.arrays = []  # (byte offset in the message, count) of every float64 array written
        self.stamps = []  # byte offset in the message of every (sec, nanosec) written

    def _align(self, n: int):
        pad = -self.size % n
        if pad:
            self.parts.append(b"\x00" * pad)
            self.size += pad

    def raw(self, data: bytes):
        self.parts.append(data)
        self.size += len(data)

    def pack(self, fmt: str, alignment: int, *values):
        self._align(alignment)
        self.raw(struct.pack("<" + fmt, *values))

    def string(self, text: str):
        data = text.encode() + b"\x00"
        self.pack("I", 4, len(data))
        self.raw(data)

    def strings(self, texts):
        self.pack("I", 4, len(texts))
        for text in texts:
            self.string(text)

    def doubles(self, values):
        self.pack("I", 4, len(values))
        if len(values):
            self._align(8)
            self.arrays.append((4 + self.size, len(values)))
            self.pack(f"{len(values)}d", 8, *values)

    def stamp(self, sec: int, nanosec: int):
        self._align(4)
        self.stamps.append(4 + self.size)
        self.pack("iI", 4, sec, nanosec)

    def header(self, sec: int, nanosec: int):
        self.stamp(sec, nanosec)
        self.string("")

    def bytes(self) -> bytes:
        return b"".join(self.parts)


class _Reader:
    def __init__(self, data: bytes):
        self.data = data
        self.offset = 0   # after the encapsulation header
        self.arrays = []  # (byte offset in data, count) of every float64 array read
        self.stamps = []  # byte offset in data of every (sec, nanosec) read

    def _align(self, n: int):
        self.offset += -self.offset % n

    def unpack(self, fmt: str, alignment: int, size: int):
        self._align(alignment)
        values = struct.unpack_from("<" + fmt, self.data, 4 + self.offset)
        self.offset += size
        return values

    def u32(self) -> int:
        return self.unpack("I", 4, 4)[0]

    def string(self) -> str:
        length = self.u32()
        text = self.data[4 + self.offset: 4 + self.offset + length - 1].decode()
        self.offset += length
        return text

    def strings(self) -> list:
        return [self.string() for _ in range(self.u32())]

    def doubles(self) -> tuple:
        n = self.u32()
        if not n:
            self.arrays.append((4 + self.offset, 0))
            return ()
        self._align(8)
        self.arrays.append((4 + self.offset, n))
        return self.unpack(f"{n}d", 8, 8 * n)

    def stamp(self) -> Stamp:
        self._align(4)
        self.stamps.append(4 + self.offset)
        return Stamp(*self.unpack("iI", 4, 8))

    def header(self) -> Header:
        return Header(self.stamp(), self.string())


def values_struct(layout) -> struct.Struct:
    """A struct reading the float64 arrays at ``layout`` [(offset, count)] of a message and skipping the
    bytes between them."""
    fmt, position = ["<"], 0
    for offset, count in layout:
        if count:
            fmt.append(f"{offset - position}x{count}d")
            position = offset + 8 * count
    return struct.Struct("".join(fmt))


class _Template:
    """A message's bytes with the offsets of its stamps and float64 arrays, to encode others like it."""

    def __init__(self, writer: _Writer):
        self.data = writer.bytes()
        self.stamps = writer.stamps
        self.arrays = [(offset, struct.Struct(f"<{count}d")) for offset, count in writer.arrays]

    def fill(self, stamps, arrays) -> bytes:
        out = bytearray(self.data)
        for offset, stamp in zip(self.stamps, stamps):
            _STAMP.pack_into(out, offset, *stamp)
        for (offset, packer), values in zip(self.arrays, (a for a in arrays if len(a))):
            packer.pack_into(out, offset, *values)
        return bytes(out)


class _Layout:
    """The layout of one fully parsed message: a message whose bytes other than its stamps and float64
    values are the same decodes as that message with its own stamps and values."""

    def __init__(self, data: bytes, reader: _Reader, parsed):
        self.parsed, self.counts, self.stamps = parsed, [count for _, count in reader.arrays], reader.stamps
        self.struct = values_struct(reader.arrays)
        variable = sorted([(offset, offset + 8) for offset in reader.stamps]
                          + [(offset, offset + 8 * count) for offset, count in reader.arrays if count])
        edges = [0] + [edge for span in variable for edge in span] + [len(data)]
        self.fixed = [(edges[i], edges[i + 1], data[edges[i]:edges[i + 1]]) for i in range(0, len(edges), 2)]
        self.size = len(data)

    @property
    def spans(self) -> tuple:
        """(start, end) of the bytes every message of this layout shares."""
        return tuple((start, end) for start, end, _ in self.fixed)

    def signature(self) -> bytes:
        """The shared bytes, in one string: a message of this layout's length whose bytes at :attr:`spans`
        join to this string is of this layout."""
        return b"".join(fixed for _, _, fixed in self.fixed)

    def read(self, data: bytes):
        """(the stamps, the float64 arrays as tuples) of ``data``, or None when its layout is another."""
        if len(data) != self.size or any(data[start:end] != fixed for start, end, fixed in self.fixed):
            return None
        return self.values(data)

    def values(self, data: bytes):
        """:meth:`read` of a message known to be of this layout."""
        values, arrays, start = self.struct.unpack_from(data), [], 0
        for count in self.counts:
            arrays.append(values[start:start + count])
            start += count
        return [Stamp(*_STAMP.unpack_from(data, offset)) for offset in self.stamps], arrays


class _Codec:
    """Cached templates and layouts of one message type, layouts by message length (topics of one type can
    share a length: /x/state and /y/state differ only in a name). Bounded: a graph has a few dozen."""

    LIMIT = 64

    def __init__(self, read, write):
        self.read_full, self.write_full = read, write
        self.templates, self.layouts = {}, {}
        # length -> [(spans, {signature: layout})]: the layouts of one length found by one dictionary look-up
        # of their shared bytes, not by trying each (N axes' states share a length: trying them in turn cost
        # O(N) comparisons a message)
        self.index = {}

    def encode(self, key, stamps, arrays, *fields) -> bytes:
        """The message of ``stamps`` [(sec, nanosec)], float64 ``arrays`` and the other ``fields`` (which,
        with the arrays' lengths, ``key`` names)."""
        template = self.templates.get(key)
        if template is None:
            if len(self.templates) >= self.LIMIT:
                self.templates.clear()
            writer = _Writer()
            self.write_full(writer, *stamps, *fields, *arrays)
            template = self.templates[key] = _Template(writer)
        return template.fill(stamps, arrays)

    def decode(self, data: bytes, assemble):
        for spans, table in self.index.get(len(data), ()):
            layout = table.get(b"".join([data[start:end] for start, end in spans]))
            if layout is not None:
                return assemble(layout.parsed, *layout.values(data))
        reader = _Reader(data)
        parsed = self.read_full(reader)
        if sum(len(c) for c in self.layouts.values()) >= self.LIMIT:
            self.layouts.clear()
            self.index.clear()
        layout = _Layout(data, reader, copy.deepcopy(parsed))
        self.layouts.setdefault(len(data), []).append(layout)
        groups, spans = self.index.setdefault(len(data), []), layout.spans
        table = next((table for group_spans, table in groups if group_spans == spans), None)
        if table is None:
            table = {}
            groups.append((spans, table))
        table[layout.signature()] = layout
        return parsed


def _write_joint_state(w: _Writer, stamp, names, position, velocity, effort):
    w.header(*stamp)
    w.strings(names)
    for values in (position, velocity, effort):
        w.doubles(values)


def _read_joint_state(r: _Reader) -> JointStateData:
    header = r.header()
    names = r.strings()
    return JointStateData(header, names, r.doubles(), r.doubles(), r.doubles())


def _assemble_joint_state(parsed: JointStateData, stamps, arrays) -> JointStateData:
    return JointStateData(Header(stamps[0], parsed.header.frame_id), list(parsed.name), *arrays)


_JOINT_STATE = _Codec(_read_joint_state, _write_joint_state)


def encode_joint_state(sec: int, nanosec: int, names, position=(), velocity=(), effort=()) -> bytes:
    """sensor_msgs/msg/JointState."""
    names = tuple(names)
    return _JOINT_STATE.encode((names, len(position), len(velocity), len(effort)), [(sec, nanosec)],
                               (position, velocity, effort), names)


def decode_joint_state(data: bytes) -> JointStateData:
    return _JOINT_STATE.decode(data, _assemble_joint_state)


def _write_joint_trajectory(w: _Writer, stamp, *rest):
    """``rest``: one time_from_start per point, the joint names, then each point's positions, velocities and
    accelerations (no effort)."""
    points = (len(rest) - 1) // 4
    times, joint_names, arrays = rest[:points], rest[points], rest[points + 1:]
    w.header(*stamp)
    w.strings(joint_names)
    w.pack("I", 4, points)
    for i in range(points):
        for values in (*arrays[3 * i:3 * i + 3], ()):
            w.doubles(values)
        w.stamp(*times[i])


def _assemble_joint_trajectory(parsed: JointTrajectoryData, stamps, arrays) -> JointTrajectoryData:
    points = [TrajectoryPointData(*arrays[4 * i:4 * i + 4], stamps[i + 1]) for i in range(len(parsed.points))]
    return JointTrajectoryData(Header(stamps[0], parsed.header.frame_id), list(parsed.joint_names), points)


def encode_joint_trajectory(sec: int, nanosec: int, joint_names, positions, velocities, accelerations,
                            time_from_start: tuple = (0, 0), preview=()) -> bytes:
    """trajectory_msgs/msg/JointTrajectory: the point of (positions, velocities, accelerations) at
    ``time_from_start``, then one point per ``preview`` item (time_from_start, positions): the reference
    ahead, positions only (no effort in any point)."""
    joint_names = tuple(joint_names)
    times = [tuple(time_from_start)] + [tuple(t) for t, _ in preview]
    arrays = [positions, velocities, accelerations]
    for _, ahead in preview:
        arrays += [ahead, (), ()]
    return _JOINT_TRAJECTORY.encode((joint_names, tuple(len(a) for a in arrays)), [(sec, nanosec), *times],
                                    arrays, joint_names)


def preview_points(ahead, sample_time_ns: int) -> list:
    """The preview points of a /reference message (``preview`` of :func:`encode_joint_trajectory`): for each
    step j = 1, 2, ... of ``ahead`` (a core Reference with a leading axis), time_from_start j Ts and the
    positions of every axis and theta."""
    return [(divmod(j * sample_time_ns, 1_000_000_000), [*position, float(theta)])
            for j, (position, theta) in enumerate(zip(ahead.position, ahead.theta), start=1)]


def decode_joint_trajectory(data: bytes) -> JointTrajectoryData:
    return _JOINT_TRAJECTORY.decode(data, _assemble_joint_trajectory)


def _read_joint_trajectory(r: _Reader) -> JointTrajectoryData:
    header = r.header()
    names = r.strings()
    points = []
    for _ in range(r.u32()):
        arrays = [r.doubles() for _ in range(4)]
        points.append(TrajectoryPointData(*arrays, r.stamp()))
    return JointTrajectoryData(header, names, points)


_JOINT_TRAJECTORY = _Codec(_read_joint_trajectory, _write_joint_trajectory)


def array_layout(type_name: str, data: bytes) -> list:
    """(byte offset, count) of every float64 array of a serialised message, in the order they are read."""
    reader = _Reader(data)
    {"sensor_msgs/msg/JointState": _read_joint_state,
     "trajectory_msgs/msg/JointTrajectory": _read_joint_trajectory}[type_name](reader)
    return reader.arrays


def encode_clock(sec: int, nanosec: int) -> bytes:
    """rosgraph_msgs/msg/Clock."""
    return _ENCAPSULATION + _STAMP.pack(sec, nanosec)
