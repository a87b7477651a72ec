"""A minimal CDR codec for the graph's three message types, so nodes publish and take raw bytes.

rclpy's own (de)serialisation builds Python message objects on every hop; the lockstep path only needs a
few float arrays and the header stamp, so the nodes encode and decode the wire format directly
(XCDR1, little endian, as rmw_fastrtps sends it: a 4-byte encapsulation header, then each field aligned
to its size relative to the end of that header). The tests check the bytes against rclpy's serializer.

Decoded messages are small objects with the field names of the ROS messages they stand for, so the
conversions in :mod:`contouring_ros.graph` work on them, on rclpy messages and on decoded bag messages alike.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass, field

__all__ = ["Stamp", "Header", "JointStateData", "TrajectoryPointData", "JointTrajectoryData", "stamp_ns",
           "encode_joint_state", "decode_joint_state", "encode_joint_trajectory", "decode_joint_trajectory",
           "encode_clock", "array_layout"]

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
            self.pack(f"{len(values)}d", 8, *values)

    def header(self, sec: int, nanosec: int):
        self.pack("iI", 4, sec, nanosec)
        self.string("")

    def bytes(self) -> bytes:
        return b"".join(self.parts)


class _Reader:
    def __init__(self, data: bytes):
        self.data = data
        self.offset = 0   # after the encapsulation header
        self.arrays = []  # (byte offset in data, count) of every float64 array read

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

    def header(self) -> Header:
        sec, nanosec = self.unpack("iI", 4, 8)
        return Header(Stamp(sec, nanosec), self.string())


def encode_joint_state(sec: int, nanosec: int, names, position=(), velocity=(), effort=()) -> bytes:
    """sensor_msgs/msg/JointState."""
    w = _Writer()
    w.header(sec, nanosec)
    w.strings(names)
    for values in (position, velocity, effort):
        w.doubles(values)
    return w.bytes()


def _read_joint_state(r: _Reader) -> JointStateData:
    header = r.header()
    names = r.strings()
    return JointStateData(header, names, r.doubles(), r.doubles(), r.doubles())


def decode_joint_state(data: bytes) -> JointStateData:
    return _read_joint_state(_Reader(data))


def encode_joint_trajectory(sec: int, nanosec: int, joint_names, positions, velocities, accelerations,
                            time_from_start: tuple = (0, 0)) -> bytes:
    """trajectory_msgs/msg/JointTrajectory with a single point (no effort)."""
    w = _Writer()
    w.header(sec, nanosec)
    w.strings(joint_names)
    w.pack("I", 4, 1)
    for values in (positions, velocities, accelerations, ()):
        w.doubles(values)
    w.pack("iI", 4, *time_from_start)
    return w.bytes()


def decode_joint_trajectory(data: bytes) -> JointTrajectoryData:
    return _read_joint_trajectory(_Reader(data))


def _read_joint_trajectory(r: _Reader) -> JointTrajectoryData:
    header = r.header()
    names = r.strings()
    points = []
    for _ in range(r.u32()):
        arrays = [r.doubles() for _ in range(4)]
        points.append(TrajectoryPointData(*arrays, Stamp(*r.unpack("iI", 4, 8))))
    return JointTrajectoryData(header, names, points)


def array_layout(type_name: str, data: bytes) -> list:
    """(byte offset, count) of every float64 array of a serialised message, in the order they are read."""
    reader = _Reader(data)
    {"sensor_msgs/msg/JointState": _read_joint_state,
     "trajectory_msgs/msg/JointTrajectory": _read_joint_trajectory}[type_name](reader)
    return reader.arrays


def encode_clock(sec: int, nanosec: int) -> bytes:
    """rosgraph_msgs/msg/Clock."""
    return _ENCAPSULATION + _STAMP.pack(sec, nanosec)
