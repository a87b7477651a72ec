"""Reading MCAP bags, hardened: whatever a file holds, reading it is bounded and ends in records or one line.

:func:`iter_records` streams a bag's schema, channel, message and metadata records front to back. Every
chunk's CRC is checked and its decompression bounded; a damaged chunk or record is a :class:`Damage`, and
reading goes on at the next chunk (found from the summary's chunk index, :func:`summary_chunks`, or by
scanning the bytes); a bag whose writer died is read up to its last complete chunk. A record is at most
64 MiB, a chunk holds at most 2**20 records, and a whole bag decompresses to at most 64 times its size
(at least 256 MiB). :func:`read_metadata` and :func:`node_reports` read a bag's metadata records and its
nodes' end-of-run reports.
"""
from __future__ import annotations

import re
import struct
from dataclasses import dataclass
from pathlib import Path

from ..wire import graph
from ..errors import BagError

__all__ = ["Damage", "iter_records", "summary_chunks", "read_metadata", "node_reports"]

_MAGIC = b"\x89MCAP0\r\n"
_FOOTER_SIZE = 1 + 8 + 20          # opcode, length, summary_start, summary_offset_start, summary_crc
_KNOWN_OPCODES = range(0x01, 0x10)
_MAX_RECORD = 64 << 20             # bytes of one record (or a chunk's decompressed records) at most
_MAX_CHUNK_RECORDS = 1 << 20       # records of one chunk at most
_MAX_SUMMARY = 64 << 20            # bytes of the summary section at most (else chunks are found by scanning)
_INFLATION, _INFLATION_FLOOR = 64, 256 << 20   # decompressed bytes of a whole bag: at most max(64 x its size, 256 MiB)
_MESSAGE_HEAD = struct.Struct("<HIQQ")         # channel id, sequence, log time, publish time
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

    def warning(self, path, sample_time: float | None = None, lost=None) -> str:
        """One line: where the bag is damaged, why, what was lost (the steps ``lost`` when known, with the
        ``sample_time`` they are steps of, else log times)."""
        after = f"read on from the chunk at byte {self.resumed_at}" if self.resumed_at is not None else \
            "nothing after it could be read"
        if lost is not None:
            what = f"steps {lost[0]}..{lost[-1]} lost ({len(lost)} step{'s' if len(lost) > 1 else ''}, t = " \
                   f"{lost[0] * sample_time:.6g}.." \
                   f"{lost[-1] * sample_time:.6g} s)" if len(lost) else "no step lost"
        else:
            start = "the start" if self.start_ns is None else f"t = {self.start_ns * 1e-9:.6g} s"
            stop = "the end" if self.end_ns is None else f"t = {self.end_ns * 1e-9:.6g} s"
            what = f"messages from {start} to {stop} lost"
        return f"{path}: the {self.kind} at byte {self.offset} is damaged " \
               f"({self.reason}): {what}; {after}"


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
    from tqdm import tqdm
    path = Path(path)
    size = path.stat().st_size
    with open(path, "rb") as stream, tqdm(total=size, desc=f"reading {path.name}", disable=not progress,
                                          leave=False, unit="B", unit_scale=True) as bar:
        if stream.read(8) != _MAGIC:
            raise BagError(f"{path}: not an MCAP file (no MCAP magic at its start)")
        walk = _Walk(path, stream, size, warnings, damaged)
        yield from walk.known     # the summary's schemas and channels: a damaged first chunk loses none of them
        yield from walk.records(bar)
    walk.warn_of_its_end()


class _Walk:
    """One walk over a bag's records from its magic to its data end: where it is, the summary it found,
    the last log time read, the decompressed bytes its chunks declared so far, and how it ended."""

    def __init__(self, path: Path, stream, size: int, warnings: list, damaged: list | None):
        self.path, self.stream, self.size, self.warnings = path, stream, size, warnings
        self.damaged = damaged
        self.own = damaged if damaged is not None else []      # Damage of each part skipped
        self.complete, self.chunks, self.known = summary_chunks(stream, size, path, warnings)
        self.indexed = {offset: (length, start, end) for offset, length, start, end in self.chunks or []}
        self.position, self.last_ns = 8, None
        self.ended = None        # None: at its data end or footer; "early": at the file's end; "damaged"
        self.inflated, self.budget = 0, max(_INFLATION * size, _INFLATION_FLOOR)
        self.readers = _record_readers()

    def records(self, bar):
        """The records from the current position on, each damaged part skipped (:meth:`_skip`); ``bar``
        advances over the bytes passed."""
        while True:
            self.stream.seek(self.position)
            head = self.stream.read(9)
            if len(head) < 9:
                self.ended = "early"
                return
            opcode, length = head[0], int.from_bytes(head[1:9], "little")
            if self.position in self.indexed and opcode == _OP_CHUNK:
                length = self.indexed[self.position][0] - 9
            end = self.position + 9 + length
            problem = _framing_problem(opcode, length, end, self.size)
            if problem is None and opcode in (_OP_DATA_END, _OP_FOOTER):
                return
            if problem is None:
                records, problem = self._read(opcode, length)
            if problem is None:
                problem = yield from self._hand_out(records)
            after = end if problem is None else self._skip(opcode, end, problem)
            if after is None:
                return
            bar.update(after - self.position)
            self.position = after

    def _read(self, opcode: int, length: int) -> tuple:
        """(records, None) of the record of ``length`` bytes after the current one's opcode and length (a
        chunk's records are read as they are handed out; a record of no interest holds none), or ([], why)
        where it cannot be read."""
        if opcode == _OP_CHUNK:
            return self._chunk(self.stream.read(length))
        if opcode == _OP_MESSAGE:
            return _message(self.stream.read(length), length)
        if opcode in self.readers:
            try:
                return [self.readers[opcode](_data_stream(self.stream.read(length)))], None
            except Exception as error:
                return [], f"a record cannot be read ({type(error).__name__})"
        return [], None

    def _chunk(self, body: bytes) -> tuple:
        """(records, None) of a chunk record's ``body`` (:func:`_chunk_records`), or ([], why) where it is
        damaged; the bag is refused as a decompression bomb once its chunks declare more than its budget."""
        declared = int.from_bytes(body[16:24], "little") if len(body) >= 24 else 0
        self.inflated += declared if declared <= _MAX_RECORD else 0
        if self.inflated > self.budget:
            raise BagError(f"{self.path}: its chunks declare more than {self.budget >> 20} MiB of records once "
                           f"decompressed ({_INFLATION} times the file's size, at least "
                           f"{_INFLATION_FLOOR >> 20} MiB; at the chunk at byte {self.position}): refused as a "
                           "decompression bomb")
        try:
            _, records = _chunk_records(body)
        except ValueError as error:
            return [], str(error)
        return records, None

    def _hand_out(self, records):
        """Yield ``records``, keeping the last log time of their messages; returns None, or why the rest
        of a chunk's records could not be read (the rest of it is lost)."""
        from mcap.records import Message
        try:
            for record in records:
                if isinstance(record, Message):
                    self.last_ns = record.log_time if self.last_ns is None else max(self.last_ns, record.log_time)
                yield record
        except ValueError as error:
            return str(error)
        return None

    def _skip(self, opcode: int, end: int, problem: str) -> int | None:
        """The byte where reading goes on after the damaged record at the current position (ending at
        ``end``), which is kept as a :class:`Damage` (a warning where the caller keeps no list of them);
        None where nothing after it can be read, or the file ends in that record (its writer died)."""
        position = self.position
        resume = _next_chunk(self.stream, position, self.size, self.chunks)
        if resume is None and self.chunks is None and end > self.size and not self.complete:
            self.ended = "early"      # the last record of a bag cut off while it was written
            return None
        start_ns, end_ns = self.indexed[position][1:] if position in self.indexed else (self.last_ns, None)
        if resume is not None and end_ns is None:
            end_ns = self.indexed[resume][1] if resume in self.indexed else _chunk_start_ns(self.stream, resume)
        kind = "chunk" if opcode == _OP_CHUNK or position in self.indexed else "record"
        self.own.append(Damage(position, kind, problem, start_ns, end_ns, resume))
        if self.damaged is None:
            self.warnings.append(self.own[-1].warning(self.path))
        if resume is None:
            self.ended = "damaged"
        return resume

    def warn_of_its_end(self):
        """A warning where the bag ends without its summary, or without a footer."""
        if self.ended == "early":
            self.warnings.append(f"{self.path}: the bag ends early (it has no summary: its writer was stopped); "
                                 "read up to its last complete chunk")
        elif self.ended is None and not self.complete:
            self.warnings.append(f"{self.path}: the bag has no footer; read up to its last complete chunk")


def _framing_problem(opcode: int, length: int, end: int, size: int) -> str | None:
    """Why the record with ``opcode`` and ``length`` (ending at byte ``end`` of a file of ``size``) cannot be
    a record of the bag; None where it can."""
    if opcode not in _KNOWN_OPCODES:
        return f"no MCAP record starts there (opcode {opcode:#04x})"
    if end > size:
        return "its length runs past the end of the file"
    if length > _MAX_RECORD + (1 << 20):
        return f"its length ({length} bytes) is more than a record may have ({_MAX_RECORD >> 20} MiB)"
    return None


def _message(body: bytes, length: int) -> tuple:
    """([message], None) of a message record's ``body`` of ``length`` bytes, or ([], why)."""
    from mcap.records import Message
    if length < _MESSAGE_HEAD.size:
        return [], "a message record too short"
    channel_id, sequence, log_time, publish_time = _MESSAGE_HEAD.unpack_from(body, 0)
    return [Message(channel_id=channel_id, sequence=sequence, log_time=log_time, publish_time=publish_time,
                    data=body[_MESSAGE_HEAD.size:])], None


def _record_readers() -> dict:
    """opcode -> the reader of the schema, channel and metadata records found outside chunks."""
    from mcap.records import Channel, Metadata, Schema
    return {_OP_SCHEMA: Schema.read, _OP_CHANNEL: Channel.read, _OP_METADATA: Metadata.read}


def _data_stream(body: bytes):
    """``body`` as the stream mcap's record readers read."""
    from io import BytesIO
    from mcap.data_stream import ReadDataStream
    return ReadDataStream(BytesIO(body))


def _chunk_start_ns(stream, offset: int):
    stream.seek(offset + 9)
    return struct.unpack("<Q", stream.read(8))[0]


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

