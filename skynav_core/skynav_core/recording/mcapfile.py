# SPDX-License-Identifier: Apache-2.0
"""MCAP files' integrity: checksums written, checked before use, and the messages of unfinished files saved.

skynav writes MCAP through rosbags, whose writer leaves every checksum at 0
(not computed). :class:`CheckedMcapWriter` fills them in: each chunk's CRC-32
of its uncompressed records, each zstd frame's content checksum, and at
close the data section's and the summary's CRC-32. :func:`check_mcap`
verifies them before a file is read and names what is damaged;
:class:`Salvage` walks an unfinished or damaged file record by record and
yields every message of every complete, intact chunk. The record layout
follows the MCAP specification (https://mcap.dev/spec).
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, BinaryIO

from backports import zstd
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.storage_mcap import McapWriter

from ..errors import SkynavError

if TYPE_CHECKING:
    from rosbags.interfaces import Connection

MAGIC = b'\x89MCAP0\r\n'
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
OP_MESSAGE_INDEX, OP_CHUNK_INDEX, OP_STATISTICS, OP_DATA_END = 0x07, 0x08, 0x0B, 0x0F
# Opcode (1 byte) and body length (8 bytes) before every record's body.
RECORD_HEAD = 9
# Footer record: head, summary start (8), summary offset start (8), summary CRC (4).
FOOTER_SIZE = RECORD_HEAD + 20
# Data end record: head and the data section CRC (4).
DATA_END_SIZE = RECORD_HEAD + 4
# A chunk body's fixed fields before its compression name: start, end, uncompressed size (8 each), CRC (4).
CHUNK_CRC_OFFSET = RECORD_HEAD + 24
# Bytes read at a time while summing a file's data section.
CRC_BLOCK = 1 << 20
# A record longer than this is taken for damage, not data (bytes): no skynav message comes near it.
MAX_RECORD = 1 << 32
# A chunk is closed (written) once its messages span this much log time (ns), or rosbags' 1 MiB: a recorder
# killed with -9 loses at most the pending chunk.
CHUNK_PERIOD = 10**9
# zstd frames carry a checksum of their content (a 4-byte XXH64 digest), checked when they are unpacked.
ZSTD_OPTIONS: dict[int, int] = {zstd.CompressionParameter.checksum_flag: 1}


class McapError(SkynavError):
    """An MCAP file whose structure or checksums are wrong; the message says what, without the file name."""


@dataclass(frozen=True)
class DamagedChunk:
    """A chunk whose contents do not match its checksum: what it held, from the file's (checked) index."""

    offset: int
    start: int  # log time of its first message (ns since the epoch)
    end: int  # log time of its last message (ns since the epoch)
    topics: tuple[str, ...]
    messages: int


@dataclass
class McapCheck:
    """What checking one MCAP file found."""

    checksummed: bool  # the file carries a data section CRC (written by a checking writer)
    damaged: list[DamagedChunk] = field(default_factory=list)
    start: int = 0  # log time of the file's first message (ns since the epoch)

    def describe(self) -> str:
        """Return one line naming the damaged chunks' topics, messages and time range (s into the recording)."""
        topics = sorted({t for chunk in self.damaged for t in chunk.topics})
        count = sum(chunk.messages for chunk in self.damaged)
        first = (min(c.start for c in self.damaged) - self.start) / 1e9
        last = (max(c.end for c in self.damaged) - self.start) / 1e9
        chunks = f'{len(self.damaged)} damaged chunk' + ('s' if len(self.damaged) > 1 else '')
        return (
            f'{chunks} (checksum mismatch): {count} messages of {", ".join(topics) or "no topic"} '
            f'logged {first:.3f}-{last:.3f} s into the recording'
        )


class _Cursor:
    """Reads MCAP's little-endian fields from a byte string; McapError when it runs out."""

    def __init__(self, data: bytes | memoryview, what: str) -> None:
        self.data, self.pos, self.what = memoryview(data), 0, what

    def take(self, size: int) -> memoryview:
        """Return the next `size` bytes."""
        if size < 0 or self.pos + size > len(self.data):
            raise McapError(f'damaged {self.what} (a field runs past its end)')
        self.pos += size
        return self.data[self.pos - size : self.pos]

    def u16(self) -> int:
        return struct.unpack('<H', self.take(2))[0]

    def u32(self) -> int:
        return struct.unpack('<I', self.take(4))[0]

    def u64(self) -> int:
        return struct.unpack('<Q', self.take(8))[0]

    def string(self) -> str:
        try:
            return bytes(self.take(self.u32())).decode()
        except UnicodeDecodeError:
            raise McapError(f'damaged {self.what} (a name is not UTF-8)') from None

    def string_map(self) -> dict[str, str]:
        sub = _Cursor(self.take(self.u32()), self.what)
        pairs = {}
        while sub.pos < len(sub.data):
            key = sub.string()
            pairs[key] = sub.string()
        return pairs

    def done(self) -> bool:
        return self.pos >= len(self.data)


def _records(data: bytes | memoryview, what: str) -> Iterator[tuple[int, memoryview]]:
    """Yield (opcode, body) of the records packed in `data`."""
    cursor = _Cursor(data, what)
    while not cursor.done():
        opcode = cursor.take(1)[0]
        yield opcode, cursor.take(cursor.u64())


@dataclass(frozen=True)
class _ChunkIndex:
    start: int
    end: int
    offset: int
    length: int
    channels: tuple[int, ...]
    message_index_length: int


@dataclass
class _Summary:
    topics: dict[int, str] = field(default_factory=dict)  # channel id -> topic
    chunks: list[_ChunkIndex] = field(default_factory=list)
    start: int = 0


def _read_footer(stream: BinaryIO, size: int) -> tuple[int, int, int]:
    """Return (summary start, summary offset start, summary CRC) from the footer."""
    if size < len(MAGIC) * 2 + FOOTER_SIZE:
        raise McapError('too short for an MCAP file')
    stream.seek(size - len(MAGIC) - FOOTER_SIZE)
    footer = stream.read(FOOTER_SIZE)
    opcode, length, summary_start, summary_offset_start, summary_crc = struct.unpack('<BQQQI', footer)
    if opcode != OP_FOOTER or length != FOOTER_SIZE - RECORD_HEAD:
        raise McapError('damaged footer')
    return summary_start, summary_offset_start, summary_crc


def _parse_summary(data: bytes) -> _Summary:
    """Return the channels and chunk indexes of a (checked) summary section."""
    summary = _Summary()
    for opcode, body in _records(data, 'index'):
        cursor = _Cursor(body, 'index')
        if opcode == OP_CHANNEL:
            channel = cursor.u16()
            cursor.u16()
            summary.topics[channel] = cursor.string()
        elif opcode == OP_CHUNK_INDEX:
            start, end, offset, length = cursor.u64(), cursor.u64(), cursor.u64(), cursor.u64()
            offsets = _Cursor(cursor.take(cursor.u32()), 'index')
            channels = []
            while not offsets.done():
                channels.append(offsets.u16())
                offsets.u64()
            summary.chunks.append(_ChunkIndex(start, end, offset, length, tuple(channels), cursor.u64()))
        elif opcode == OP_STATISTICS:
            cursor.take(8 + 2 + 4 + 4 + 4 + 4)
            summary.start = cursor.u64()
    return summary


def _crc_of_range(stream: BinaryIO, start: int, stop: int) -> int:
    """Return the CRC-32 of the file's bytes [start, stop)."""
    stream.seek(start)
    crc, left = 0, stop - start
    while left > 0:
        block = stream.read(min(CRC_BLOCK, left))
        if not block:
            raise McapError('truncated data section')
        crc, left = zlib.crc32(block, crc), left - len(block)
    return crc


def _summary_crc(summary: bytes, summary_start: int, summary_offset_start: int) -> int:
    """Return the CRC-32 of the summary section and the footer's fields before its CRC, as the footer carries it."""
    footer_fields = struct.pack('<BQQQ', OP_FOOTER, FOOTER_SIZE - RECORD_HEAD, summary_start, summary_offset_start)
    return zlib.crc32(footer_fields, zlib.crc32(summary))


def unpack_chunk(body: bytes | memoryview) -> tuple[int, int, bytes]:
    """Return (start, end, records) of a chunk record's body; McapError when it does not match its checksums."""
    cursor = _Cursor(body, 'chunk')
    start, end, size, crc = cursor.u64(), cursor.u64(), cursor.u64(), cursor.u32()
    compression = cursor.string()
    packed = cursor.take(cursor.u64())
    try:
        if compression == 'zstd':
            records = zstd.decompress(packed)
        elif compression == '':
            records = bytes(packed)
        else:
            raise McapError(f'unsupported chunk compression {compression!r}')
    except zstd.ZstdError as exc:
        raise McapError(f'damaged chunk ({exc})') from None
    if len(records) != size or (crc and zlib.crc32(records) != crc):
        raise McapError('damaged chunk (checksum mismatch)')
    return start, end, records


def _chunk_is_intact(stream: BinaryIO, chunk: _ChunkIndex) -> bool:
    """Return whether the chunk at the index's offset is a chunk record that matches its checksum."""
    stream.seek(chunk.offset)
    record = stream.read(chunk.length)
    if len(record) != chunk.length or record[0] != OP_CHUNK:
        return False
    if struct.unpack_from('<Q', record, 1)[0] != chunk.length - RECORD_HEAD:
        return False
    try:
        unpack_chunk(memoryview(record)[RECORD_HEAD:])
    except McapError:
        return False
    return True


def check_mcap(path: Path) -> McapCheck:
    """Check a finished MCAP file's summary, data section and (if that is damaged) every chunk.

    Raises McapError when the index (summary) or anything outside the chunks is damaged;
    returns the damaged chunks otherwise (none for an intact file). Files without checksums
    (CRC 0) pass unchecked.
    """
    size = path.stat().st_size
    with path.open('rb') as stream:
        summary_start, summary_offset_start, summary_crc = _read_footer(stream, size)
        footer_start = size - len(MAGIC) - FOOTER_SIZE
        if summary_start == 0:
            return McapCheck(checksummed=False)
        if not DATA_END_SIZE + len(MAGIC) <= summary_start <= footer_start:
            raise McapError('damaged footer (its summary offset is outside the file)')
        stream.seek(summary_start)
        summary_bytes = stream.read(footer_start - summary_start)
        if summary_crc:
            if _summary_crc(summary_bytes, summary_start, summary_offset_start) != summary_crc:
                raise McapError('damaged index (summary checksum mismatch)')
        summary = _parse_summary(summary_bytes)
        stream.seek(summary_start - DATA_END_SIZE)
        opcode, length, data_crc = struct.unpack('<BQI', stream.read(DATA_END_SIZE))
        if opcode != OP_DATA_END or length != DATA_END_SIZE - RECORD_HEAD:
            raise McapError('damaged data end record')
        check = McapCheck(checksummed=bool(data_crc), start=summary.start)
        if not data_crc or _crc_of_range(stream, 0, summary_start - DATA_END_SIZE) == data_crc:
            return check
        for chunk in summary.chunks:
            if not _chunk_is_intact(stream, chunk):
                count = (chunk.message_index_length - 15 * len(chunk.channels)) // 16
                topics = tuple(sorted({summary.topics.get(c, f'channel {c}') for c in chunk.channels}))
                check.damaged.append(DamagedChunk(chunk.offset, chunk.start, chunk.end, topics, count))
        if not check.damaged:
            raise McapError('damaged outside its messages (data checksum mismatch, every chunk intact)')
        return check


def _patch_checksums(path: Path) -> None:
    """Write the data section's and the summary's CRC-32 into a finished file's data end and footer records."""
    size = path.stat().st_size
    with path.open('r+b') as stream:
        summary_start, summary_offset_start, _ = _read_footer(stream, size)
        footer_start = size - len(MAGIC) - FOOTER_SIZE
        data_end = summary_start - DATA_END_SIZE
        data_crc = _crc_of_range(stream, 0, data_end)
        stream.seek(data_end + RECORD_HEAD)
        stream.write(struct.pack('<I', data_crc))
        stream.seek(summary_start)
        summary_bytes = stream.read(footer_start - summary_start)
        stream.seek(footer_start + FOOTER_SIZE - 4)
        stream.write(struct.pack('<I', _summary_crc(summary_bytes, summary_start, summary_offset_start)))


class CheckedMcapWriter(McapWriter):
    """rosbags' MCAP storage writer with every checksum filled in (rosbags leaves them at 0)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        if self.compression == 'zstd':
            self.compressor = lambda data: zstd.compress(data, options=ZSTD_OPTIONS)
        self.bio.flush()  # the header: even a recording killed before its first chunk is an MCAP file

    def write(self, connection: Connection, timestamp: int, data: bytes | memoryview) -> None:
        """Add one message; close the chunk once it spans CHUNK_PERIOD of log time."""
        super().write(connection, timestamp, data)
        if self.chunk.message_end_time - self.chunk.message_start_time >= CHUNK_PERIOD:
            self.close_chunk()

    def close_chunk(self) -> None:
        """Write the pending chunk, then its CRC-32 into the chunk record's CRC field."""
        crc = zlib.crc32(self.chunk.bio.getbuffer())
        start = self.bio.tell()
        super().close_chunk()
        end = self.bio.tell()
        self.bio.seek(start + CHUNK_CRC_OFFSET)
        self.bio.write(struct.pack('<I', crc))
        self.bio.seek(end)
        self.bio.flush()  # a finished chunk reaches the file: what `skynav bag recover` saves after kill -9

    def close(self, version: int, metadata: str) -> None:
        """Finish the file, then fill in the data section's and the summary's checksums."""
        super().close(version, metadata)
        _patch_checksums(self.path)


class CheckedWriter(Writer):
    """rosbags' rosbag2 writer whose MCAP files carry every checksum."""

    STORAGE_PLUGINS = {**Writer.STORAGE_PLUGINS, StoragePlugin.MCAP: CheckedMcapWriter}


@dataclass(frozen=True)
class SalvagedChannel:
    """A channel found in an unfinished file: topic, type, its definition and offered QoS (as rosbag2 writes)."""

    id: int
    topic: str
    msgtype: str
    msgdef: str
    offered_qos: str


@dataclass(frozen=True)
class SalvagedMessage:
    """A complete message of an intact chunk."""

    channel: int
    log_time: int
    data: bytes


class Salvage:
    """Walk an MCAP file (finished or not) record by record; yield channels and messages of intact chunks.

    The walk stops at the first record that is cut off or malformed; a chunk that does not
    match its checksum is skipped and counted.
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self.chunks = 0  # intact chunks read
        self.damaged = 0  # chunks skipped: checksum mismatch or malformed records
        self.stopped = ''  # why the walk ended before a footer ('' when it reached one)
        self._schemas: dict[int, tuple[str, str]] = {}

    def records(self) -> Iterator[SalvagedChannel | SalvagedMessage]:
        """Yield the channels (each before its first message) and the messages, in file order."""
        with self.path.open('rb') as stream:
            if stream.read(len(MAGIC)) != MAGIC:
                raise McapError('not an MCAP file (it does not start with the MCAP magic bytes)')
            while True:
                head = stream.read(RECORD_HEAD)
                if len(head) < RECORD_HEAD:
                    self.stopped = 'the file ends without a footer'
                    return
                opcode, length = struct.unpack('<BQ', head)
                if length > MAX_RECORD:
                    self.stopped = 'a damaged record header'
                    return
                body = stream.read(length)
                if len(body) < length:
                    self.stopped = 'the last record is cut off'
                    return
                if opcode == OP_FOOTER:
                    return
                if opcode == OP_CHUNK:
                    yield from self._chunk(body)
                else:
                    yield from self._record(opcode, body)

    def _chunk(self, body: bytes) -> Iterator[SalvagedChannel | SalvagedMessage]:
        try:
            _, _, records = unpack_chunk(body)
            found = [item for opcode, inner in _records(records, 'chunk') for item in self._record(opcode, inner)]
        except McapError:
            self.damaged += 1
            return
        self.chunks += 1
        yield from found

    def _record(self, opcode: int, body: bytes | memoryview) -> Iterator[SalvagedChannel | SalvagedMessage]:
        cursor = _Cursor(body, 'record')
        if opcode == OP_SCHEMA:
            schema, name, _ = cursor.u16(), cursor.string(), cursor.string()
            self._schemas[schema] = (name, bytes(cursor.take(cursor.u32())).decode(errors='replace'))
        elif opcode == OP_CHANNEL:
            channel, schema, topic, _ = cursor.u16(), cursor.u16(), cursor.string(), cursor.string()
            msgtype, msgdef = self._schemas.get(schema, ('', ''))
            qos = cursor.string_map().get('offered_qos_profiles', '')
            yield SalvagedChannel(channel, topic, msgtype, msgdef, qos)
        elif opcode == OP_MESSAGE:
            channel, _, log_time, _ = cursor.u16(), cursor.u32(), cursor.u64(), cursor.u64()
            yield SalvagedMessage(channel, log_time, bytes(cursor.take(len(cursor.data) - cursor.pos)))
