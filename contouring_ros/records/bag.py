"""MCAP bags in the rosbag2 layout, written without rosbag2 and read without rclpy.

Writing: profile ``ros2``, one schema per message type with encoding ``ros2msg`` named ``pkg/msg/Type``
(the .msg text with its dependencies, as rosbag2 stores it), CDR payloads exactly as they went over the
wire, zstd chunks, and a summary with statistics, so that rosbag2, Foxglove, PlotJuggler and the
``mcap``/``rosbags`` readers open it. The experiment's YAML is stored as the metadata record
``contouring_ros.experiment``. Log and publish times are the messages' step stamps.

Reading, in two steps around the experiment's validation, which is not this module's (the caller parses the
experiment once: :func:`contouring_ros.records.scoring.read_run`): :func:`read_contents` streams a bag's records and
returns the experiment text it stores with the columns of its topics, then :func:`decode_run` turns those into
per-step arrays, checked against the parsed experiment, as a :class:`RecordedRun` that carries it.
"""
from __future__ import annotations

import contextlib
import os
import re
import struct
import sys
from dataclasses import dataclass
from pathlib import Path

from array import array

import numpy as np

from ..wire import cdr, graph
from ..core.simulation import SimulationResult, first_divergence, step_time
from ..errors import BagError, ContouringError
from ..core.interpolation import reference_ahead
from ..experiment.build import build_curve, build_schedule, reference_preview
from ..experiment.catalogue import GLOBALS
from ..experiment.model import Experiment
from ..experiment.schema import MAX_FILE_BYTES
from ..experiment.validate import is_axis_name

__all__ = ["message_definition", "BagWriter", "RecordedRun", "BagContents", "reading", "read_contents", "decode_run",
           "read_metadata", "node_reports", "iter_records", "summary_chunks", "write_simulation", "EXPERIMENT_METADATA",
           "RUN_METADATA"]

EXPERIMENT_METADATA = "contouring_ros.experiment"
RUN_METADATA = "contouring_ros.run"      # wall-clock figures of the recording
_BUILTINS = {"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32",
             "uint32", "int64", "uint64", "string", "wstring"}
_SEPARATOR = "=" * 80
QOS_METADATA = ("- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n"
                "  deadline:\n    sec: 2147483647\n    nsec: 4294967295\n"
                "  lifespan:\n    sec: 2147483647\n    nsec: 4294967295\n  liveliness: 1\n"
                "  liveliness_lease_duration:\n    sec: 2147483647\n    nsec: 4294967295\n"
                "  avoid_ros_namespace_conventions: false\n")


def _msg_text(package: str, name: str) -> str:
    """The .msg file of a message type, from <prefix>/share/<package>/msg of an ament prefix (a sourced ROS
    install) or of this Python environment (the PyPI message wheels)."""
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p] + [sys.prefix]
    for prefix in prefixes:
        path = Path(prefix) / "share" / package / "msg" / f"{name}.msg"
        if path.is_file():
            return path.read_text()
    raise BagError(f"no definition of {package}/msg/{name} under {', '.join(prefixes)}")


def _field_types(text: str, package: str):
    """Complex field types ('pkg/Type') a .msg text refers to, in order."""
    for line in text.splitlines():
        tokens = line.split("#", 1)[0].split()
        if len(tokens) < 2 or "=" in tokens[1]:       # blank, or a constant
            continue
        base = re.sub(r"(<=\d+)?(\[.*\])?$", "", tokens[0])
        if base not in _BUILTINS:
            yield base if "/" in base else f"{package}/{base}"


def message_definition(type_name: str) -> str:
    """The ros2msg schema text of 'pkg/msg/Type': its .msg file, then each dependency once, depth first."""
    package, _, name = type_name.split("/")
    parts, seen = [_msg_text(package, name)], set()
    stack = list(_field_types(parts[0], package))
    while stack:
        dep = stack.pop(0)
        if dep in seen:
            continue
        seen.add(dep)
        dep_package, dep_name = dep.split("/")[0], dep.split("/")[-1]
        text = _msg_text(dep_package, dep_name)
        parts.append(f"{_SEPARATOR}\nMSG: {dep_package}/{dep_name}\n{text}")
        stack.extend(_field_types(text, dep_package))
    return "\n".join(part.rstrip("\n") for part in parts) + "\n"


class BagWriter:
    """Write CDR messages to an MCAP file in the rosbag2 layout; use as a context manager.

    Parameters
    ----------
    path : path-like
        The .mcap file to create.
    topics : iterable of (name, 'pkg/msg/Type')
    metadata : dict of str -> dict of str to str
        Metadata records written at the start.
    background : bool
        Write (and compress) on a thread of its own: :meth:`write` only queues the message, so the caller
        (the recorder's take loop, or the composed layout's one loop) never waits for a chunk to compress.
    """

    BATCH = 256    # messages a background writer collects before handing them to its thread

    def __init__(self, path, topics, *, metadata=None, chunk_size: int = 256 * 1024, background: bool = False):
        from mcap.writer import CompressionType, Writer
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.path, "wb")
        self._writer = Writer(self._file, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self._writer.start(profile="ros2", library="contouring_ros")
        schemas, self._channels, self._sequence = {}, {}, {}
        for topic, type_name in topics:
            if type_name not in schemas:
                schemas[type_name] = self._writer.register_schema(
                    name=type_name, encoding="ros2msg", data=message_definition(type_name).encode())
            self._channels[topic] = self._writer.register_channel(
                topic=topic, message_encoding="cdr", schema_id=schemas[type_name],
                metadata={"offered_qos_profiles": QOS_METADATA})
            self._sequence[topic] = 0
        for name, record in (metadata or {}).items():
            self._writer.add_metadata(name, record)
        self.closed = False
        self._queue = self._thread = self._gate = None
        self._batch = []
        if background:
            import queue
            import threading
            self._queue = queue.SimpleQueue()
            self._thread = threading.Thread(target=self._drain, name="bag writer", daemon=True)
            self._thread.start()

    def _drain(self):
        while True:
            batch = self._queue.get()
            if batch is None:
                return
            for call in batch:
                gate = self._gate
                if gate is not None:
                    gate.wait()
                call[0](*call[1:])

    def write_only_while(self, gate):
        """From now on the writer thread (background writers) writes only while the threading.Event ``gate``
        is set; None: whenever it has something to write. The composed layout's realtime loop sets its gate
        while it waits for its next tick and clears it while it ticks: the thread's Python work then never
        competes with a tick for the interpreter (unpaced, a batch written during ticks made them up to 2 ms
        longer, every 256 messages). What is queued while the gate is closed waits, in memory."""
        previous, self._gate = self._gate, gate
        if previous is not None:
            previous.set()       # release a thread waiting on the old gate

    def _do(self, *call):
        if self._queue is not None:
            self._batch.append(call)
            if len(self._batch) >= self.BATCH:
                self.flush()
        else:
            call[0](*call[1:])

    def flush(self):
        """Hand what :meth:`write` collected to the writer thread (background writers; else nothing)."""
        if self._queue is not None and self._batch:
            self._queue.put(self._batch)
            self._batch = []

    def add_metadata(self, name: str, record: dict):
        """Add a metadata record (str -> str) before the bag is closed."""
        self._do(self._writer.add_metadata, name, record)
        self.flush()

    def write(self, topic: str, stamp_ns: int, data: bytes):
        """Append one serialised message, logged at its stamp (a background writer collects BATCH
        messages before it hands them to its thread: waking the thread for each message cost the caller
        about 40 us a message, most of the recorder's cost in the composed layout)."""
        self._do(self._write, topic, stamp_ns, data)

    def _write(self, topic: str, stamp_ns: int, data: bytes):
        self._writer.add_message(self._channels[topic], log_time=stamp_ns, data=data, publish_time=stamp_ns,
                                 sequence=self._sequence[topic])
        self._sequence[topic] += 1

    def close(self):
        """Write what is queued, then the summary (statistics, indexes), and close the file."""
        if not self.closed:
            self.closed = True
            if self._thread is not None:
                self.write_only_while(None)
                self.flush()
                self._queue.put(None)
                self._thread.join()
            self._writer.finish()
            self._file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


@dataclass
class RecordedRun:
    """A run as read back from a bag.

    Attributes
    ----------
    experiment_text : str
        The experiment YAML stored in the bag (or the one given for it), verbatim.
    axes : list of str
    result : SimulationResult
        The per-step signals of every step for which each topic was recorded.
    payloads : dict
        topic -> list of raw CDR payloads (only when asked for).
    warnings : list of str
        What the reader had to make do with (a bag cut off before its summary).
    experiment : Experiment or None
        ``experiment_text`` parsed (once, by the reader's caller); None where it does not validate here
        (e.g. a part program it names is not on this machine).
    experiment_error : Exception or None
        Why ``experiment`` is None: the error its validation raised.
    """

    experiment_text: str
    axes: list
    result: SimulationResult
    payloads: dict
    warnings: list
    experiment: Experiment | None = None
    experiment_error: Exception | None = None

    @property
    def complete_steps(self) -> int:
        return len(self.result.time)

    def require_experiment(self) -> Experiment:
        """The run's Experiment; where its text did not validate here, the error it failed with is raised."""
        if self.experiment is None:
            raise self.experiment_error or BagError("the run's experiment was not parsed")
        return self.experiment


def read_metadata(path) -> dict:
    """All metadata records of a bag: name -> dict of str to str."""
    from mcap.reader import make_reader
    with open(path, "rb") as stream:
        return {record.name: dict(record.metadata) for record in make_reader(stream).iter_metadata()}


def node_reports(path) -> dict:
    """Each node's end-of-run report from the bag's /diagnostics: node name -> {key: value} (the last
    status of that node whose message starts with 'completed'), decoded with the ROS 2 decoder alone."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    reports = {}
    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        diagnostics = [channel.topic for channel in reader.get_summary().channels.values()
                       if channel.topic.endswith(graph.DIAGNOSTICS)] if reader.get_summary() else [graph.DIAGNOSTICS]
        for _, _, _, array_msg in reader.iter_decoded_messages(topics=diagnostics):
            for status in array_msg.status:
                if status.message.startswith("completed"):
                    reports[status.name] = {kv.key: kv.value for kv in status.values}
    return reports


def _step_times(stamps_ns, sample_time) -> np.ndarray:
    """Times of the recorded steps, computed as the simulation computes them (k Ts) when Ts is known."""
    if sample_time is None or not np.isfinite(sample_time):
        return np.array(stamps_ns, dtype=float) * 1e-9
    ts_ns = int(round(sample_time * 1e9))
    return np.array([step_time(stamp // ts_ns, sample_time) for stamp in stamps_ns])


_MAGIC = b"\x89MCAP0\r\n"
_FOOTER_SIZE = 1 + 8 + 20          # opcode, length, summary_start, summary_offset_start, summary_crc
_KNOWN_OPCODES = range(0x01, 0x10)
_MAX_RECORD = 64 << 20             # bytes of one record (or a chunk's decompressed records) at most
_MAX_CHUNK_RECORDS = 1 << 20       # records of one chunk at most
_MAX_SUMMARY = 64 << 20            # bytes of the summary section at most (else chunks are found by scanning)
_INFLATION, _INFLATION_FLOOR = 64, 256 << 20   # decompressed bytes of a whole bag: at most max(64 x its size, 256 MiB)
_MESSAGE_HEAD = struct.Struct("<HIQQ")         # channel id, sequence, log time, publish time
_MAX_TOPICS = 4096                 # JointState and JointTrajectory topics read at most (a graph of 8 axes has 19)
_OP_FOOTER, _OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK, _OP_CHUNK_INDEX, _OP_METADATA, _OP_DATA_END = \
    0x02, 0x03, 0x04, 0x05, 0x06, 0x08, 0x0C, 0x0F


@dataclass
class Damage:
    """A part of a bag that could not be read: the record at byte ``offset`` (a chunk whose CRC, compression
    or framing is wrong, or a record whose length is), and the log times [start_ns, end_ns] its messages
    could have had (None: from the start / to the end of the recording)."""

    offset: int
    kind: str                     # chunk | record
    reason: str
    start_ns: int | None
    end_ns: int | None
    resumed_at: int | None        # byte of the next chunk read, None: nothing after it could be read


def summary_chunks(stream, size: int, path, warnings: list):
    """(complete, chunks, records): whether the file ends with a valid footer, and, when the summary is there
    and its CRC holds (else None, []), its chunk index as sorted (offset, length, start_ns, end_ns) and its
    schema and channel records."""
    import zlib
    from io import BytesIO
    from mcap.data_stream import ReadDataStream
    from mcap.records import Channel, ChunkIndex, Schema
    if size < 8 + _FOOTER_SIZE + 8:
        return False, None, []
    stream.seek(size - 8 - _FOOTER_SIZE)
    tail = stream.read(_FOOTER_SIZE + 8)
    if tail[-8:] != _MAGIC or tail[0] != _OP_FOOTER or int.from_bytes(tail[1:9], "little") != 20:
        return False, None, []
    summary_start, _, summary_crc = struct.unpack_from("<QQI", tail, 9)
    footer_at = size - 8 - _FOOTER_SIZE
    if summary_start == 0:
        return True, None, []
    if not 8 <= summary_start < footer_at:
        warnings.append(f"{path}: the footer is damaged (its summary offset {summary_start} is outside the "
                        "file); chunks are found by scanning")
        return False, None, []
    if footer_at - summary_start > _MAX_SUMMARY:
        warnings.append(f"{path}: the footer's summary section is {footer_at - summary_start} bytes, more than "
                        f"{_MAX_SUMMARY >> 20} MiB; chunks are found by scanning")
        return False, None, []
    stream.seek(summary_start)
    summary = stream.read(footer_at - summary_start)
    if summary_crc and zlib.crc32(tail[:1 + 8 + 16], zlib.crc32(summary)) != summary_crc:
        warnings.append(f"{path}: the summary is damaged (CRC mismatch); chunks are found by scanning")
        return False, None, []
    chunks, records, at = [], [], 0
    try:
        while at + 9 <= len(summary):
            opcode, length = summary[at], int.from_bytes(summary[at + 1:at + 9], "little")
            if opcode == _OP_CHUNK_INDEX:
                index = ChunkIndex.read(ReadDataStream(BytesIO(summary[at + 9:at + 9 + length])))
                chunks.append((index.chunk_start_offset, index.chunk_length, index.message_start_time,
                               index.message_end_time))
            elif opcode in (_OP_SCHEMA, _OP_CHANNEL):
                body = ReadDataStream(BytesIO(summary[at + 9:at + 9 + length]))
                records.append((Schema if opcode == _OP_SCHEMA else Channel).read(body))
            at += 9 + length
    except Exception:   # a CRC that holds over a summary we cannot parse: not ours to guess
        warnings.append(f"{path}: the summary cannot be parsed; chunks are found by scanning")
        return True, None, []
    return True, sorted(chunks), records


def _decompressed(chunk) -> bytes:
    """A chunk's records, decompressed with a bound on the real output: never more than the size the chunk
    declares (itself at most _MAX_RECORD) plus one byte, whatever the compressed data says about its own
    size. ValueError when the data holds more or less than declared."""
    declared = chunk.uncompressed_size
    if chunk.compression == "zstd":
        import zstandard
        reader = zstandard.ZstdDecompressor().stream_reader(chunk.data)
        parts, got = [], 0
        while got <= declared:
            piece = reader.read(min(declared + 1 - got, 1 << 20))
            if not piece:
                break
            parts.append(piece)
            got += len(piece)
        data = b"".join(parts)
    elif chunk.compression == "lz4":
        import lz4.frame
        data = lz4.frame.LZ4FrameDecompressor().decompress(chunk.data, max_length=declared + 1)
    else:
        data = chunk.data
    if len(data) != declared:
        raise ValueError(f"it decompresses to more than the {declared} bytes it declares" if len(data) > declared
                         else f"it decompresses to {len(data)} bytes, not the {declared} it declares")
    return data


def _chunk_records(body: bytes):
    """(chunk, records) of a chunk record's ``body`` (after opcode and length): the header and CRC checked
    and the records decompressed (bounded, :func:`_decompressed`) before this returns; ``records`` is a
    generator that raises ValueError with the reason at a record it cannot read. Raises ValueError with
    the reason when the chunk is damaged."""
    import zlib
    from io import BytesIO
    from mcap.data_stream import ReadDataStream
    from mcap.records import Chunk
    try:
        chunk = Chunk.read(ReadDataStream(BytesIO(body)))
    except Exception as error:
        raise ValueError(f"its header cannot be read ({type(error).__name__})") from None
    if chunk.compression not in ("", "zstd", "lz4") or chunk.message_start_time > chunk.message_end_time:
        raise ValueError("its header is damaged")
    if chunk.uncompressed_size > _MAX_RECORD:
        raise ValueError(f"it declares {chunk.uncompressed_size} bytes of records, more than the "
                         f"{_MAX_RECORD >> 20} MiB a chunk may hold")
    try:
        data = _decompressed(chunk)
    except ValueError:
        raise
    except Exception as error:
        raise ValueError(f"it cannot be decompressed ({type(error).__name__})") from None
    if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
        raise ValueError("CRC mismatch")
    return chunk, _records_of(data)


def _records_of(data: bytes):
    """The schema, channel and message records of a chunk's decompressed ``data``, one at a time (a chunk
    of a million tiny records is never held as a million objects). At most _MAX_CHUNK_RECORDS records; a
    private record (opcode 0x80 and up) is skipped; anything else, or a record cut off, raises ValueError."""
    from io import BytesIO
    from mcap.data_stream import ReadDataStream
    from mcap.records import Channel, Message, Schema
    readers = {_OP_SCHEMA: Schema.read, _OP_CHANNEL: Channel.read}
    unpack, at, size, count = _MESSAGE_HEAD.unpack_from, 0, len(data), 0
    while at < size:
        count += 1
        if count > _MAX_CHUNK_RECORDS:
            raise ValueError(f"it holds more than {_MAX_CHUNK_RECORDS} records")
        if at + 9 > size:
            raise ValueError("its last record is cut off")
        opcode, length = data[at], int.from_bytes(data[at + 1:at + 9], "little")
        end = at + 9 + length
        if end > size:
            raise ValueError("its records cannot be read (a record runs past the chunk's end)")
        if opcode == _OP_MESSAGE:
            if length < _MESSAGE_HEAD.size:
                raise ValueError("its records cannot be read (a message record too short)")
            channel_id, sequence, log_time, publish_time = unpack(data, at + 9)
            yield Message(channel_id=channel_id, sequence=sequence, log_time=log_time, publish_time=publish_time,
                          data=data[at + 9 + _MESSAGE_HEAD.size:end])
        elif opcode in readers:
            try:
                record = readers[opcode](ReadDataStream(BytesIO(data[at + 9:end])))
            except Exception as error:
                raise ValueError(f"its records cannot be read ({type(error).__name__})") from None
            yield record
        elif opcode < 0x80:
            raise ValueError(f"its records cannot be read (a record of opcode {opcode:#04x} in a chunk)")
        at = end


def _plausible_chunk(head: bytes, at: int, size: int) -> bool:
    """Whether the bytes ``head`` (at file offset ``at``) start a chunk record: opcode, a length inside the
    file, ordered times, a known compression and a records length that fills the record exactly."""
    if len(head) < 49 or head[0] != _OP_CHUNK:
        return False
    length = int.from_bytes(head[1:9], "little")
    start, end, uncompressed, _, name_length = struct.unpack_from("<QQQII", head, 9)
    if at + 9 + length > size or start > end or uncompressed > _MAX_RECORD or name_length > 4:
        return False
    name = head[41:41 + name_length]
    if name not in (b"", b"zstd", b"lz4") or len(head) < 49 + name_length:
        return False
    records = int.from_bytes(head[41 + name_length:49 + name_length], "little")
    return length == 40 + name_length + records


def _next_chunk(stream, after: int, size: int, chunks):
    """The offset of the first chunk that starts after byte ``after``: from the summary's index when there is
    one, else by scanning the bytes for a plausible chunk record; None when there is none."""
    if chunks is not None:
        later = [offset for offset, *_ in chunks if offset > after]
        for offset in later:
            stream.seek(offset)
            if _plausible_chunk(stream.read(64), offset, size):
                return offset
        if not later:
            return None
        # the index names places where no chunk starts (it belongs to another file's layout): scan instead
    block, at = 1 << 20, after + 1
    while at < size:
        stream.seek(at)
        data = stream.read(block + 64)
        # candidates found by the regex engine (opcode, then a known compression name where a chunk has it),
        # not byte by byte: a file full of 0x06 bytes is scanned as fast as any other
        for match in _CHUNK_HEAD.finditer(data, 0, min(len(data), block + 49)):
            found = match.start()
            if found >= block:
                break
            if _plausible_chunk(data[found:found + 64], at + found, size):
                return at + found
        at += block
    return None


_CHUNK_HEAD = re.compile(rb"\x06(?=.{36}(?:\x00\x00\x00\x00|\x03\x00\x00\x00lz4|\x04\x00\x00\x00zstd))", re.DOTALL)


def iter_records(path, warnings: list, progress: bool = False, damaged: list | None = None):
    """(schema, channel, message, metadata) records of a bag read front to back, streaming.

    Every chunk's CRC is checked. A damaged chunk (or a record whose framing is broken) is skipped and
    reading goes on at the next chunk: the summary's chunk index says where it starts when the summary is
    there (and its CRC holds), else the bytes are scanned for the next chunk record. Each damaged part is a
    :class:`Damage` appended to ``damaged`` (decode_run turns them into warnings naming the steps lost), or,
    without that list, a warning with its time range. A bag whose writer died has no summary: everything
    up to its last complete record (chunk) is read, and a warning says where the file ends. ``progress``
    shows a bar over the file's bytes.
    """
    from io import BytesIO
    from mcap.data_stream import ReadDataStream
    from mcap.records import Channel, Message, Metadata, Schema
    from tqdm import tqdm
    path = Path(path)
    size = path.stat().st_size
    readers = {_OP_SCHEMA: Schema.read, _OP_CHANNEL: Channel.read, _OP_METADATA: Metadata.read}
    own = damaged if damaged is not None else []
    with open(path, "rb") as stream, tqdm(total=size, desc=f"reading {path.name}", disable=not progress,
                                          leave=False, unit="B", unit_scale=True) as bar:
        if stream.read(8) != _MAGIC:
            raise BagError(f"{path}: not an MCAP file (no MCAP magic at its start)")
        complete, chunks, known = summary_chunks(stream, size, path, warnings)
        indexed = {offset: (length, start, end) for offset, length, start, end in chunks or []}
        yield from known        # the summary's schemas and channels: a damaged first chunk loses none of them
        position, last_ns, ended = 8, None, None
        inflated, budget = 0, max(_INFLATION * size, _INFLATION_FLOOR)
        while True:
            stream.seek(position)
            head = stream.read(9)
            if len(head) < 9:
                ended = "early"
                break
            opcode, length = head[0], int.from_bytes(head[1:9], "little")
            if position in indexed and opcode == _OP_CHUNK:
                length = indexed[position][0] - 9
            end = position + 9 + length
            problem = None
            if opcode not in _KNOWN_OPCODES:
                problem = f"no MCAP record starts there (opcode {opcode:#04x})"
            elif end > size:
                problem = "its length runs past the end of the file"
            elif length > _MAX_RECORD + (1 << 20):
                problem = f"its length ({length} bytes) is more than a record may have ({_MAX_RECORD >> 20} MiB)"
            if problem is None and opcode == _OP_DATA_END:
                break
            if problem is None and opcode == _OP_FOOTER:
                break
            body = stream.read(length) if problem is None and opcode in (_OP_CHUNK, _OP_MESSAGE, *readers) else b""
            records = []
            if problem is None and opcode == _OP_CHUNK:
                declared = int.from_bytes(body[16:24], "little") if len(body) >= 24 else 0
                inflated += declared if declared <= _MAX_RECORD else 0
                if inflated > budget:
                    raise BagError(f"{path}: its chunks declare more than {budget >> 20} MiB of records once "
                                   f"decompressed ({_INFLATION} times the file's size, at least "
                                   f"{_INFLATION_FLOOR >> 20} MiB; at the chunk at byte {position}): refused as a "
                                   "decompression bomb")
                try:
                    _, records = _chunk_records(body)
                except ValueError as error:
                    problem = str(error)
                body = None
            elif problem is None and opcode == _OP_MESSAGE:
                if length < _MESSAGE_HEAD.size:
                    problem = "a message record too short"
                else:
                    channel_id, sequence, log_time, publish_time = _MESSAGE_HEAD.unpack_from(body, 0)
                    records = [Message(channel_id=channel_id, sequence=sequence, log_time=log_time,
                                       publish_time=publish_time, data=body[_MESSAGE_HEAD.size:])]
            elif problem is None and opcode in readers:
                try:
                    records = [readers[opcode](ReadDataStream(BytesIO(body)))]
                except Exception as error:
                    problem = f"a record cannot be read ({type(error).__name__})"
            if problem is None:
                try:
                    for record in records:
                        if isinstance(record, Message):
                            last_ns = record.log_time if last_ns is None else max(last_ns, record.log_time)
                        yield record
                except ValueError as error:      # a chunk's record that cannot be read: the rest of it is lost
                    problem = str(error)
                else:
                    bar.update(end - position)
                    position = end
                    continue
            resume = _next_chunk(stream, position, size, chunks)
            if resume is None and chunks is None and end > size and not complete:
                ended = "early"      # the last record of a bag cut off while it was written
                break
            start_ns, end_ns = indexed[position][1:] if position in indexed else (last_ns, None)
            if resume is not None and end_ns is None:
                end_ns = indexed[resume][1] if resume in indexed else _chunk_start_ns(stream, resume)
            kind = "chunk" if opcode == _OP_CHUNK or position in indexed else "record"
            own.append(Damage(position, kind, problem, start_ns, end_ns, resume))
            if damaged is None:
                warnings.append(_damage_warning(path, own[-1]))
            if resume is None:
                ended = "damaged"
                break
            bar.update(resume - position)
            position = resume
    if ended == "early":
        warnings.append(f"{path}: the bag ends early (it has no summary: its writer was stopped); read up to its "
                        "last complete chunk")
    elif ended is None and not complete:
        warnings.append(f"{path}: the bag has no footer; read up to its last complete chunk")


def _chunk_start_ns(stream, offset: int):
    stream.seek(offset + 9)
    return struct.unpack("<Q", stream.read(8))[0]


def _damage_warning(path, damage: Damage, sample_time: float | None = None, lost=None) -> str:
    """One line: where the bag is damaged, why, what was lost (steps when known, else log times)."""
    after = f"read on from the chunk at byte {damage.resumed_at}" if damage.resumed_at is not None else \
        "nothing after it could be read"
    if lost is not None:
        what = f"steps {lost[0]}..{lost[-1]} lost ({len(lost)} step{'s' if len(lost) > 1 else ''}, t = " \
               f"{lost[0] * sample_time:.6g}.." \
               f"{lost[-1] * sample_time:.6g} s)" if len(lost) else "no step lost"
    else:
        start = "the start" if damage.start_ns is None else f"t = {damage.start_ns * 1e-9:.6g} s"
        stop = "the end" if damage.end_ns is None else f"t = {damage.end_ns * 1e-9:.6g} s"
        what = f"messages from {start} to {stop} lost"
    return f"{path}: the {damage.kind} at byte {damage.offset} is damaged " \
           f"({damage.reason}): {what}; {after}"


class _TopicColumns:
    """The float arrays of one topic's messages, kept flat in typed arrays (8 bytes a value).

    A topic's messages share their layout (same names, same array lengths): the first message's array
    offsets (:func:`cdr.array_layout`) give one precompiled struct for all of them, checked by the message
    length; a message of another length gets its layout worked out again.
    """

    def __init__(self, topic: str, type_name: str):
        self.topic, self.type_name = topic, type_name
        self.size = self.width = None
        self.stamps, self.values = array("q"), array("d")
        self.problem = None       # why this topic's messages stopped being read (a message that cannot be)
        self.first = self.counts = None   # the first message read; its arrays' lengths

    def add(self, data: bytes):
        """Keep one message's numbers; a message that cannot be read (another layout, not CDR of the type)
        sets ``problem`` and ends the topic's reading: decode_run refuses the bag for it only when scoring needs
        the topic, and otherwise warns (a stray topic never makes a bag unreadable)."""
        if self.problem is not None:
            return
        try:
            if len(data) != self.size:
                layout = cdr.array_layout(self.type_name, data)
                counts = [count for _, count in layout]
                if self.width is not None and counts != self.counts:
                    self.problem = f"a message with arrays of {counts} values after messages with {self.counts}"
                    return
                self.size, self.width, self.counts = len(data), sum(counts), counts
                self.struct = cdr.values_struct(layout)
            values = self.struct.unpack_from(data, 0)
            stamp = cdr.stamp_ns(data)
        except Exception as error:    # not a CDR message of its type
            self.problem = f"a message that is not a {self.type_name} ({type(error).__name__})"
            return
        if self.first is None:
            self.first = bytes(data)
        self.stamps.append(stamp)
        self.values.extend(values)

    def array(self, index: int, rows: np.ndarray) -> np.ndarray:
        """Field ``index`` (the index-th float array of the message) at the message rows ``rows``."""
        table = np.frombuffer(self.values, dtype=float).reshape(-1, self.width)
        start = sum(self.counts[:index])
        return table[rows, start:start + self.counts[index]]


_KEPT_TYPES = {"sensor_msgs/msg/JointState", "trajectory_msgs/msg/JointTrajectory"}


@dataclass
class BagContents:
    """What a bag's records hold, read without the experiment being validated (:func:`read_contents`); the
    caller parses ``experiment_text`` and gives the result to :func:`decode_run`."""

    path: Path
    experiment_text: str          # the experiment YAML stored in the bag, or the one given for it
    given: bool                   # the text was given (a bag recorded without one, or another one's)
    stored_sample_time: str | None
    kept: dict                    # topic -> _TopicColumns of the JointState and JointTrajectory topics
    payloads: dict                # topic -> raw CDR payloads (only when asked for)
    warnings: list
    damaged: list                 # Damage of each part of the file that could not be read


@contextlib.contextmanager
def reading(path):
    """Whatever reading the bag at ``path`` meets becomes one BagError line naming the bag (KeyboardInterrupt
    passes): the reader's own refusals as they are, a ContouringError prefixed with the path, anything else
    (crafted contents no check foresaw) as 'cannot read the bag', never a traceback."""
    try:
        yield
    except (BagError, KeyboardInterrupt):
        raise
    except ContouringError as error:
        raise BagError(f"{path}: {error}") from None
    except Exception as error:
        raise BagError(f"{path}: cannot read the bag ({type(error).__name__}: {error})") from None


def read_contents(path, keep_payloads: bool = False, experiment_text: str | None = None,
                  progress: bool = False) -> BagContents:
    """Stream a bag's records and keep what a run is made of: the columns of its JointState and
    JointTrajectory topics, the experiment text it stores (``experiment_text`` instead when given: a bag
    recorded without one) and its stored sample time. Nothing here validates the experiment.

    Works on bags of the recorder, on rosbag2 MCAP bags with the same topics and types, and on bags whose
    writer died (see :func:`iter_records`); what the reader had to make do with is in the ``warnings``.
    Whatever the file holds, what cannot be read is a BagError (one line naming the bag and the problem).
    """
    path = Path(path)
    with reading(path):
        return _read_contents(path, keep_payloads, experiment_text, progress)


def decode_run(contents: BagContents, experiment=None, divergence_bound: float | None = None,
               experiment_error: Exception | None = None) -> RecordedRun:
    """The run a bag's contents hold: per-step arrays of the steps for which every topic was recorded.

    ``experiment`` is the Experiment of ``contents.experiment_text``, parsed by the caller (None where it
    does not validate here, ``experiment_error`` saying why): the bag is checked against it (sample time,
    axes, steps) and the run carries it. ``divergence_bound`` is the bound of its whole path (None: the
    recorded reference's own size). Every problem is a BagError (one line) or a warning.
    """
    with reading(contents.path):
        return _decode_run(contents, experiment, divergence_bound, experiment_error)


def _checked_sample_time(path, stored, experiment, warnings: list) -> float:
    """The sample time of a bag: the experiment's, and the metadata's (``stored``, a string or None) only as
    long as it is a sample time the validator would take and agrees with the experiment's."""
    low, high = GLOBALS["sample_time"].bounds
    value = None
    if stored is not None:
        try:
            value = float(stored)
        except ValueError:
            value = float("nan")
        if not low <= value <= high:
            what = f"the bag's {EXPERIMENT_METADATA} sample_time {stored!r} is not a sample time ({low:g} to {high:g} s)"
            if experiment is None:
                raise BagError(f"{path}: {what}, and the experiment gives none")
            warnings.append(f"{path}: {what}; the experiment's ({experiment.sample_time:g} s) is used")
            value = None
    if experiment is not None:
        if value is not None and value != experiment.sample_time:
            warnings.append(f"{path}: the bag's {EXPERIMENT_METADATA} sample_time {value:g} s differs from its "
                            f"experiment's ({experiment.sample_time:g} s); the experiment's is used")
        return experiment.sample_time
    if value is None:
        raise BagError(f"{path}: no sample time (neither the {EXPERIMENT_METADATA} metadata nor a valid experiment "
                       "gives one)")
    return value


def _graph_namespace(path, kept: dict, warnings: list) -> str:
    """The namespace of the graph a bag recorded: the one whose /reference has the most messages; another
    topic ending in /reference is named in a warning and left out (a stray publisher never makes a bag
    unreadable)."""
    prefixes = {}
    for name, columns in kept.items():
        if name.endswith(graph.REFERENCE) and columns.type_name == "trajectory_msgs/msg/JointTrajectory":
            prefixes[name[:-len(graph.REFERENCE)] or "/"] = len(columns.stamps)
    if not prefixes:
        return "/"
    chosen = max(sorted(prefixes), key=lambda prefix: prefixes[prefix])
    others = [prefix for prefix in sorted(prefixes) if prefix != chosen]
    if others:
        where = lambda prefix: (prefix.rstrip("/") + graph.REFERENCE)  # noqa: E731
        warnings.append(f"{path}: {', '.join(f'{where(p)} ({prefixes[p]} messages)' for p in others)} left out: "
                        f"the graph read is the one of {where(chosen)} ({prefixes[chosen]} messages)")
    return chosen


def _check_joint_names(path, joint_names, experiment, given: bool = False) -> list:
    """The axes a bag's /reference names (its joint names but the last, which must be theta): refused in one
    line when they are none, repeat one, are not axis names, or are not the experiment's axes."""
    names = list(joint_names)
    axes = names[:-1]
    shown = ", ".join(repr(name) for name in names[:10]) + (", ..." if len(names) > 10 else "")
    if not names or names[-1] != graph.THETA_NAME or not axes:
        raise BagError(f"{path}: its {graph.REFERENCE} names the joints [{shown}]: expected one or more axes, then "
                       f"'{graph.THETA_NAME}'")
    if len(set(axes)) != len(axes):
        twice = next(axis for axis in axes if axes.count(axis) > 1)
        raise BagError(f"{path}: its {graph.REFERENCE} names the axis {twice!r} twice ([{shown}])")
    for axis in axes:
        if not is_axis_name(axis):
            raise BagError(f"{path}: its {graph.REFERENCE} names {axis!r}, not an axis name ([{shown}])")
    if experiment is not None and list(experiment.axes) != axes:
        source = f"--experiment {experiment.name}" if given else "its experiment"
        raise BagError(f"{path}: {source} has axes {', '.join(experiment.axes)}; the bag has {', '.join(axes)} (the "
                       f"joints its {graph.REFERENCE} names)")
    return axes


def _on_grid(path, stamps: np.ndarray, sample_time: float, n_steps: int | None, warnings: list) -> np.ndarray:
    """The complete steps' stamps that are steps of the experiment: t_k = k Ts with 0 <= k < n_steps (the
    nodes refuse any other stamp, so no run records one); the others are left out, with a warning."""
    ts_ns = int(round(sample_time * 1e9))
    k = stamps // ts_ns
    good = (stamps >= 0) & (stamps % ts_ns == 0)
    if n_steps is not None:
        good &= k < n_steps
    if good.all():
        return stamps
    bad = stamps[~good]
    end = f" (the experiment ends at t = {(n_steps - 1) * sample_time:g} s)" if n_steps is not None else ""
    warnings.append(f"{path}: {len(bad)} step{'s' if len(bad) > 1 else ''} stamped off the experiment's steps "
                    f"(t = {', '.join(f'{t * 1e-9:.6g}' for t in bad[:3])}{' ...' if len(bad) > 3 else ''} s; "
                    f"steps are k x {sample_time:g} s){end}: left out")
    return stamps[good]


def _graph_named(topic: str) -> bool:
    """Whether ``topic`` ends as one of the graph's recorded JointState / JointTrajectory topics does
    (/reference, /contour_error, /ccc/correction, /<axis>/state, /<axis>/command), under any namespace."""
    return topic.rsplit("/", 1)[-1] in _GRAPH_TOPIC_NAMES


_GRAPH_TOPIC_NAMES = {topic.name.rsplit("/", 1)[-1] for topic in graph.recorded_topics(["axis"], True, True)
                      if topic.type in _KEPT_TYPES}


def _read_contents(path: Path, keep_payloads: bool, experiment_text: str | None, progress: bool) -> BagContents:
    from mcap.records import Channel, Metadata, Schema
    if not path.is_file():
        raise BagError(f"{path}: no such bag")
    given = experiment_text is not None
    kept: dict = {}
    payloads: dict = {}
    warnings: list = []
    damaged: list = []            # Damage of each part of the file that could not be read
    schemas, keepers = {}, {}     # channel id -> _TopicColumns of the topics scoring needs
    stored_sample_time = None
    counts, full = {False: 0, True: 0}, {False: False, True: False}   # topics kept, by _graph_named
    for record in iter_records(path, warnings, progress, damaged):
        if isinstance(record, Schema):
            schemas[record.id] = record
        elif isinstance(record, Channel):
            type_name = schemas[record.schema_id].name if record.schema_id in schemas else None
            if type_name in _KEPT_TYPES and not record.topic.endswith(graph.DIAGNOSTICS):
                # graph-named topics and the others are counted apart: strays listed first cannot crowd out
                # the run's own topics
                group = _graph_named(record.topic)
                if record.topic not in kept and counts[group] >= _MAX_TOPICS:
                    if not full[group]:
                        warnings.append(f"{path}: more than {_MAX_TOPICS} JointState and JointTrajectory topics"
                                        f"{' named as the graph names its own' if group else ''}; from "
                                        f"{record.topic} on, the others are left out")
                        full[group] = True
                    continue
                counts[group] += record.topic not in kept
                columns = kept.setdefault(record.topic, _TopicColumns(record.topic, type_name))
                if columns.type_name == type_name:    # a second channel of the topic with another type: not read
                    keepers[record.id] = columns
        elif isinstance(record, Metadata):
            if record.name == EXPERIMENT_METADATA:
                experiment_text = experiment_text or record.metadata.get("yaml")
                stored_sample_time = record.metadata.get("sample_time")
        else:
            columns = keepers.get(record.channel_id)
            if columns is None:
                continue
            columns.add(record.data)
            if keep_payloads:
                payloads.setdefault(columns.topic, []).append(bytes(record.data))
    if damaged and not experiment_text:
        raise BagError(f"{path}: the bag is damaged ({damaged[0].reason} at byte {damaged[0].offset}) and holds no "
                       f"experiment ('{EXPERIMENT_METADATA}' metadata); give the experiment file that produced it")
    if not experiment_text:
        raise BagError(f"{path}: the bag holds no experiment ('{EXPERIMENT_METADATA}' metadata); give the "
                       "experiment file that produced it")
    if len(experiment_text) > MAX_FILE_BYTES:
        raise BagError(f"{path}: its experiment ('{EXPERIMENT_METADATA}' metadata) is {len(experiment_text)} "
                       f"characters; an experiment file has at most {MAX_FILE_BYTES}")
    return BagContents(path, experiment_text, given, stored_sample_time, kept, payloads, warnings, damaged)


def _decode_run(contents: BagContents, experiment, divergence_bound: float | None,
                experiment_error: Exception | None) -> RecordedRun:
    path, given, kept, payloads = contents.path, contents.given, contents.kept, contents.payloads
    warnings, damaged = list(contents.warnings), contents.damaged
    sample_time = _checked_sample_time(path, contents.stored_sample_time, experiment, warnings)
    # a graph run under a namespace (/m1/reference ...): its topics by the graph's own names
    namespace = _graph_namespace(path, kept, warnings)
    if namespace != "/":
        kept = {name[len(namespace):]: columns for name, columns in kept.items() if name.startswith(namespace + "/")}
        payloads = {name[len(namespace):]: data for name, data in payloads.items() if name.startswith(namespace + "/")}
    reference = kept.get(graph.REFERENCE)
    if reference is None or reference.type_name != "trajectory_msgs/msg/JointTrajectory" or \
            (not len(reference.stamps) and reference.problem is None):
        raise BagError(f"{path}: the bag has no {graph.REFERENCE} messages")
    if reference.problem is not None and not len(reference.stamps):
        raise BagError(f"{path}: {namespace.rstrip('/')}{graph.REFERENCE}: {reference.problem}")
    axes = _check_joint_names(path, cdr.decode_joint_trajectory(reference.first).joint_names, experiment, given)
    needed = [graph.REFERENCE, graph.CONTOUR_ERROR, graph.CORRECTION] + \
        [graph.state_topic(a) for a in axes] + [graph.command_topic(a) for a in axes]
    for topic in needed:
        if topic not in kept:
            raise BagError(f"{path}: the bag has no {topic} messages")
        expected = "trajectory_msgs/msg/JointTrajectory" if topic == graph.REFERENCE else "sensor_msgs/msg/JointState"
        if kept[topic].type_name != expected:
            raise BagError(f"{path}: {namespace.rstrip('/')}{topic} is a {kept[topic].type_name}, not a {expected}")
        if kept[topic].problem is not None:
            raise BagError(f"{path}: {namespace.rstrip('/')}{topic}: {kept[topic].problem}")
    for topic, columns in kept.items():
        if columns.problem is not None and topic not in needed:
            warnings.append(f"{path}: {columns.topic} left out (not a topic of the graph's steps): {columns.problem}")
    n = len(axes)     # the arrays each topic's messages must have (index -> values at least)
    shapes = {graph.REFERENCE: {0: n + 1, 1: n + 1, 2: n + 1}, graph.CONTOUR_ERROR: {0: n + 2}, graph.CORRECTION: {2: n}}
    for topic in needed:
        columns = kept[topic]
        shape = shapes.get(topic, {0: 1, 1: 1} if topic.endswith("/state") else {2: 1})
        if columns.counts is not None and any(len(columns.counts) <= i or columns.counts[i] < count
                                              for i, count in shape.items()):
            raise BagError(f"{path}: {namespace.rstrip('/')}{topic}: messages with arrays of {columns.counts} values; "
                           f"the graph's for axes {', '.join(axes)} have at least {shape} (array: values)")
    silent = [topic for topic in needed if not len(kept[topic].stamps)]
    if silent:
        raise BagError(f"{path}: no complete step: {', '.join(silent)} recorded no messages")
    stamps = np.asarray(kept[needed[0]].stamps)
    for topic in needed[1:]:
        stamps = np.intersect1d(stamps, np.asarray(kept[topic].stamps))
    stamps = _on_grid(path, stamps, sample_time, experiment.n_steps if experiment is not None else None, warnings)
    if not len(stamps):
        raise BagError(f"{path}: no complete step (no stamp has a message on every one of {', '.join(needed)})")
    rows = {}
    for topic in needed:   # the row of each step's message (the last one where a stamp repeats)
        own = np.asarray(kept[topic].stamps)
        order = np.argsort(own, kind="stable")
        last = order[np.searchsorted(own[order], stamps, side="right") - 1]
        rows[topic] = last
    if damaged:
        last_ns = max(int(kept[topic].stamps[-1]) for topic in needed)
        warnings[:0] = [_damage_warning(path, damage, sample_time, _lost_steps(damage, stamps, sample_time, last_ns))
                        for damage in damaged]

    def column(topic, index, count=None):
        return kept[topic].array(index, rows[topic])[:, :count]

    def per_axis(topic_of, index):
        return np.hstack([column(topic_of(a), index, 1) for a in axes])

    reference_pos, reference_vel, reference_acc = (column(graph.REFERENCE, i) for i in (0, 1, 2))
    estimate = column(graph.CONTOUR_ERROR, 0)
    result = SimulationResult(
        time=_step_times(stamps.tolist(), sample_time), theta=reference_pos[:, n],
        reference_position=reference_pos[:, :n], reference_velocity=reference_vel[:, :n],
        reference_acceleration=reference_acc[:, :n],
        position=per_axis(graph.state_topic, 0), velocity=per_axis(graph.state_topic, 1),
        estimate_theta=estimate[:, n + 1], estimate_vector=estimate[:, :n], estimate_signed=estimate[:, n],
        correction=column(graph.CORRECTION, 2), command=per_axis(graph.command_topic, 2))
    diverged = first_divergence(result.time, result.position, result.reference_position, divergence_bound)
    if diverged:
        k, diverged = diverged
        if k == 0:
            raise BagError(f"{path}: the run {diverged}, before any complete step")
        warnings.append(f"the run {diverged}; read up to the step before it ({k} steps)")
        result = SimulationResult(**{name: value[:k] for name, value in vars(result).items()})
    return RecordedRun(experiment_text=contents.experiment_text, axes=axes, result=result, payloads=payloads,
                       warnings=warnings, experiment=experiment, experiment_error=experiment_error)


def _lost_steps(damage: Damage, complete_ns: np.ndarray, sample_time: float, last_ns: int) -> np.ndarray:
    """The steps k within the damaged part's time range (to the last recorded step when it runs to the end)
    that have no complete step in the bag."""
    ts_ns = int(round(sample_time * 1e9))
    start = 0 if damage.start_ns is None else -(-damage.start_ns // ts_ns)
    stop = (last_ns if damage.end_ns is None else damage.end_ns) // ts_ns
    steps = np.arange(start, max(stop, start - 1) + 1, dtype=np.int64)
    return steps[~np.isin(steps * ts_ns, complete_ns)]


def write_simulation(path, experiment, result) -> Path:
    """Write an in-process run as the recorder would have recorded it (same topics, types and payloads).

    Used to record long runs without the node graph (benchmarks, sweeps) and as a second writer in tests.
    """
    axes = list(experiment.axes)
    ts_ns = int(round(experiment.sample_time * 1e9))
    names = axes + [graph.THETA_NAME]
    metadata = {EXPERIMENT_METADATA: {"yaml": experiment.text, "axes": ",".join(axes),
                                      "steps": str(len(result.time)), "sample_time": repr(experiment.sample_time)}}
    preview = reference_preview(experiment)
    curve = build_curve(experiment) if preview else None
    schedule = build_schedule(experiment, curve)
    with BagWriter(path, [(t.name, t.type) for t in graph.topics(axes)], metadata=metadata) as writer:
        for k in range(len(result.time)):
            stamp = graph.step_to_stamp(k, ts_ns)
            ns = k * ts_ns
            # theta's rates as the interpolator computes them (the result keeps theta alone)
            _, theta_dot, theta_ddot = schedule(step_time(k, experiment.sample_time))
            writer.write(graph.CLOCK, ns, cdr.encode_clock(*stamp))
            # the preview a servo reading ahead got (the plan's times without exact stops' holds)
            ahead = cdr.preview_points(reference_ahead(curve, schedule, k, result.time[k], preview,
                                                       experiment.sample_time), ts_ns) if preview else ()
            writer.write(graph.REFERENCE, ns, cdr.encode_joint_trajectory(
                *stamp, names, [*result.reference_position[k], result.theta[k]],
                [*result.reference_velocity[k], float(theta_dot)], [*result.reference_acceleration[k], float(theta_ddot)],
                preview=ahead))
            for i, axis in enumerate(axes):
                writer.write(graph.state_topic(axis), ns, cdr.encode_joint_state(
                    *stamp, [axis], [result.position[k, i]], [result.velocity[k, i]]))
            writer.write(graph.CONTOUR_ERROR, ns, cdr.encode_joint_state(
                *stamp, graph.estimate_names(axes),
                [*result.estimate_vector[k], result.estimate_signed[k], result.estimate_theta[k]]))
            writer.write(graph.CORRECTION, ns, cdr.encode_joint_state(*stamp, axes, effort=result.correction[k]))
            for i, axis in enumerate(axes):
                writer.write(graph.command_topic(axis), ns, cdr.encode_joint_state(
                    *stamp, [axis], effort=[result.command[k, i]]))
    return Path(path)
