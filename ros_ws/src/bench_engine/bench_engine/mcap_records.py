"""Defensive MCAP primitives: record parsing, decompression and summary checks for the bag reader
(bench_engine.bag_reader) and recovery (bench_engine.recovery, through :class:`RecordScan`).

The reader walks MCAP records itself, defensively: a damaged or hostile file (tests/test_fuzz_readers.py) ends
in a BagError naming the file and what is wrong (bench_engine.bag_errors), never in a library's error, a hang
or an allocation its bytes do not justify. Every offset and length is checked against the bytes that are
there (the file's size, the record's, the chunk's) before it is used; a chunk's claimed uncompressed size
against MAX_CHUNK_BYTES before anything is decompressed, and the output grows only with the data really there
(in reads of at most _PIECE bytes, never past the claim); CRCs are checked where the file has them (summary,
chunks), so a flipped bit reads as damage, not as other numbers.
"""

from __future__ import annotations

import io
import os
import struct
import zlib
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any, BinaryIO

import lz4.frame
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import AttachmentIndex, Channel, ChunkIndex, Message, MetadataIndex, Schema, Statistics
from mcap.summary import Summary

from bench_engine.bag_errors import BagDamaged

MAX_CHUNK_BYTES = 1 << 30
"""The largest uncompressed chunk the reader accepts. rosbag2 and bench_engine.bag_writer write chunks of 768 KiB; a
chunk holding one large message is about as large as that message. A chunk claiming more is refused before
anything is allocated."""
MAX_RECORD_BYTES = 2 * MAX_CHUNK_BYTES
"""The largest record the reader reads whole (a chunk with its compressed data; a schema, channel or message
outside chunks): a record claiming more is refused before it is read."""
MAX_SUMMARY_BYTES = 1 << 28
"""The largest summary section the reader reads (that of a 100 GB bag of 768 KiB chunks is a few tens of MB): a
footer placing the summary further back is refused before it is read."""
_PIECE = 8 << 20  # decompressed bytes per read: the most a chunk's claimed size makes the reader allocate ahead
_MAGIC = b"\x89MCAP0\r\n"
_RECORD_PREFIX = 1 + 8  # an MCAP record's opcode (uint8) and length (uint64)
_MESSAGE_HEADER = struct.Struct("<HIQQ")  # a message record's channel id, sequence, log time and publish time
_CHUNK_HEADER = struct.Struct("<QQQII")  # message start and end time, uncompressed size and CRC, compression length
_FOOTER = struct.Struct("<BQQQI")  # opcode, length (20), summary start, summary offset start, summary CRC
_U64, _U32, _U16 = struct.Struct("<Q"), struct.Struct("<I"), struct.Struct("<H")
_OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK = (
    int(Opcode.SCHEMA),
    int(Opcode.CHANNEL),
    int(Opcode.MESSAGE),
    int(Opcode.CHUNK),
)
_OP_FOOTER, _OP_DATA_END = int(Opcode.FOOTER), int(Opcode.DATA_END)
_OP_HEADER, _OP_MESSAGE_INDEX = int(Opcode.HEADER), int(Opcode.MESSAGE_INDEX)
_OP_METADATA, _OP_ATTACHMENT = int(Opcode.METADATA), int(Opcode.ATTACHMENT)
_DATA_SECTION = {
    _OP_HEADER,
    _OP_SCHEMA,
    _OP_CHANNEL,
    _OP_MESSAGE,
    _OP_CHUNK,
    _OP_MESSAGE_INDEX,
    _OP_ATTACHMENT,
    _OP_METADATA,
    _OP_DATA_END,
    _OP_FOOTER,
}  # what a scan from the start may meet
_SUMMARY_RECORDS = {
    int(Opcode.SCHEMA): Schema,
    int(Opcode.CHANNEL): Channel,
    int(Opcode.CHUNK_INDEX): ChunkIndex,
    int(Opcode.STATISTICS): Statistics,
    int(Opcode.METADATA_INDEX): MetadataIndex,
    int(Opcode.ATTACHMENT_INDEX): AttachmentIndex,
}
_COMPRESSIONS = ("", "zstd", "lz4")


class _Cut(Exception):
    """A record parser read past its record's end."""


class _RecordBody(ReadDataStream):
    """One record's bytes for mcap's record parsers: reading past them raises :class:`_Cut` (mcap's own stream
    returns fewer bytes, or allocates whatever a length field claims)."""

    def __init__(self, body: bytes | memoryview) -> None:
        super().__init__(io.BytesIO())
        self._body = body

    def read(self, length: int) -> bytes:
        if length < 0 or self._count + length > len(self._body):
            raise _Cut
        start = self._count
        self._count += length
        return bytes(self._body[start : self._count])


def _parse(record_class: type, body: bytes | memoryview, path: Path, what: str) -> Any:
    """A record of ``record_class`` (mcap.records) parsed from its body, which must hold it."""
    try:
        return record_class.read(_RecordBody(body))
    except (_Cut, UnicodeDecodeError, struct.error):
        raise BagDamaged(f"{path}: {what} is cut short or garbled") from None


def _read_at(f: BinaryIO, size: int, offset: int, length: int, path: Path, what: str) -> bytes:
    """``length`` bytes of the file at ``offset``, refused unless the file (``size`` bytes) holds them."""
    if offset < 0 or length < 0 or offset + length > size:
        raise BagDamaged(
            f"{path}: {what} at byte {offset} claims {length} bytes, past the end of the file ({size} bytes)"
        )
    f.seek(offset)
    data = f.read(length)
    if len(data) != length:
        raise BagDamaged(f"{path}: {what} at byte {offset}: the file ended early (did it change while read?)")
    return data


def _records(buf: bytes, start: int, end: int, path: Path, where: str) -> Iterator[tuple[int, int, int]]:
    """``(opcode, body start, body end)`` of each record of ``buf[start:end]``, each checked to fit in it."""
    pos = start
    while pos < end:
        body = pos + _RECORD_PREFIX
        if body > end:
            raise BagDamaged(f"{path}: {where}: the record at byte {pos} is cut short")
        stop = body + _U64.unpack_from(buf, pos + 1)[0]
        if stop > end:
            raise BagDamaged(
                f"{path}: {where}: the record at byte {pos} claims {stop - body} bytes, {end - body} are left"
            )
        yield buf[pos], body, stop
        pos = stop


def read_summary(f: BinaryIO, size: int, path: Path, rebuild: str) -> Summary:
    """The summary section of an MCAP file (schemas, channels, chunk indexes, statistics), checked: magic at both
    ends, the footer, the summary CRC, every record fitting, and the indexes against the data section."""
    if size < 2 * len(_MAGIC) + _FOOTER.size:
        raise BagDamaged(f"{path} holds {size} bytes, too few for an MCAP file: it is truncated{rebuild}")
    if _read_at(f, size, 0, len(_MAGIC), path, "the magic") != _MAGIC:
        raise BagDamaged(f"{path} is not an MCAP file (no MCAP magic at its start)")
    footer_at = size - len(_MAGIC) - _FOOTER.size
    tail = _read_at(f, size, footer_at, _FOOTER.size + len(_MAGIC), path, "the footer")
    opcode, length, start, _offsets, crc = _FOOTER.unpack_from(tail)
    footer_ok = tail[_FOOTER.size :] == _MAGIC and opcode == _OP_FOOTER and length == _FOOTER.size - _RECORD_PREFIX
    if not footer_ok or not start:
        raise BagDamaged(f"{path} has no summary section: the file is truncated{rebuild}")
    if not len(_MAGIC) <= start <= footer_at:
        raise BagDamaged(f"{path}: the footer puts the summary at byte {start}, outside the file{rebuild}")
    if footer_at - start > MAX_SUMMARY_BYTES:
        raise BagDamaged(
            f"{path}: the footer puts the summary at byte {start}, {footer_at - start} bytes before "
            f"it: more than the reader's limit of {MAX_SUMMARY_BYTES} (bench_engine.mcap_records."
            f"MAX_SUMMARY_BYTES){rebuild}"
        )
    data = _read_at(f, size, start, footer_at - start, path, "the summary section")
    if crc and zlib.crc32(tail[: _FOOTER.size - 4], zlib.crc32(data)) != crc:
        raise BagDamaged(f"{path}: the summary section's CRC does not match: it is corrupt{rebuild}")
    summary = Summary()
    for opcode, body, stop in _records(data, 0, len(data), path, "the summary section"):
        record_class = _SUMMARY_RECORDS.get(opcode)
        if record_class is None:
            continue
        record = _parse(
            record_class,
            memoryview(data)[body:stop],
            path,
            f"the summary's {record_class.__name__} record at byte {start + body - _RECORD_PREFIX}",
        )
        if record_class is Schema:
            summary.schemas[record.id] = record
        elif record_class is Channel:
            summary.channels[record.id] = record
        elif record_class is ChunkIndex:
            summary.chunk_indexes.append(record)
        elif record_class is Statistics:
            summary.statistics = record
        elif record_class is MetadataIndex:
            summary.metadata_indexes.append(record)
        else:
            summary.attachment_indexes.append(record)
    _check_summary(summary, start, path, rebuild)
    return summary


def _check_summary(summary: Summary, data_end: int, path: Path, rebuild: str) -> None:
    """The summary's references resolve, and its chunk indexes point into the data section with sizes the reader
    accepts."""
    for channel in summary.channels.values():
        if channel.schema_id and channel.schema_id not in summary.schemas:
            raise BagDamaged(
                f"{path}: channel {channel.topic!r} names schema {channel.schema_id}, which the summary "
                f"does not hold{rebuild}"
            )
    for index in summary.chunk_indexes:
        where = f"the summary's index of a chunk at byte {index.chunk_start_offset}"
        if index.chunk_start_offset < len(_MAGIC) or index.chunk_start_offset + index.chunk_length > data_end:
            raise BagDamaged(f"{path}: {where} ({index.chunk_length} bytes) points outside the data section{rebuild}")
        if index.chunk_length > MAX_RECORD_BYTES:
            raise BagDamaged(
                f"{path}: {where} claims {index.chunk_length} bytes, more than the reader's limit of "
                f"{MAX_RECORD_BYTES} (bench_engine.mcap_records.MAX_RECORD_BYTES)"
            )
        if index.compression not in _COMPRESSIONS:
            raise BagDamaged(f"{path}: {where}: compression {index.compression!r} is not one MCAP defines")
        if index.uncompressed_size > MAX_CHUNK_BYTES:
            raise BagDamaged(
                f"{path}: {where} claims {index.uncompressed_size} bytes uncompressed, more than the "
                f"reader's limit of {MAX_CHUNK_BYTES} (bench_engine.mcap_records.MAX_CHUNK_BYTES)"
            )
        unknown = set(index.message_index_offsets) - set(summary.channels)
        if unknown:
            raise BagDamaged(
                f"{path}: {where} lists channel(s) {sorted(unknown)}, which the summary does not hold{rebuild}"
            )


def _decompress(data: memoryview, compression: str, size: int, path: Path, where: str) -> bytes:
    """A chunk's ``data`` decompressed, which must give exactly the ``size`` bytes the chunk claims. The claim is
    checked against :data:`MAX_CHUNK_BYTES` first, and the output read in pieces of at most :data:`_PIECE`
    bytes (at once when one zstd frame claims the same size, no more than that), so what is allocated follows
    the data really there, whatever the claim or the frame header says."""
    if size > MAX_CHUNK_BYTES:
        raise BagDamaged(
            f"{path}: {where} claims {size} bytes uncompressed, more than the reader's limit of "
            f"{MAX_CHUNK_BYTES} (bench_engine.mcap_records.MAX_CHUNK_BYTES)"
        )
    if compression == "":
        if len(data) != size:
            raise BagDamaged(f"{path}: {where} holds {len(data)} bytes but claims {size}")
        return bytes(data)
    pieces: list[bytes] = []
    total = 0
    try:
        if compression == "zstd" and size <= _PIECE and zstandard.frame_content_size(data) == size:
            # one frame that says what the chunk says: decompressed at once (what it allocates is that size)
            pieces.append(zstandard.ZstdDecompressor().decompress(data, max_output_size=size))
            total = len(pieces[0])
            read = None
        elif compression == "zstd":
            read = zstandard.ZstdDecompressor().stream_reader(data, read_across_frames=True).read
        elif compression == "lz4":
            read = _lz4_reader(data)
        else:
            raise BagDamaged(f"{path}: {where}: compression {compression!r} is not one MCAP defines")
        while read is not None:
            piece = read(min(size - total, _PIECE) + 1)
            if not piece:
                break
            total += len(piece)
            pieces.append(piece)
            if total > size:
                raise BagDamaged(f"{path}: {where} decompresses to more than the {size} bytes it claims")
    except (zstandard.ZstdError, RuntimeError, EOFError, OSError) as err:  # lz4 raises RuntimeError
        raise BagDamaged(f"{path}: {where} does not decompress ({compression}: {err})") from None
    if total != size:
        raise BagDamaged(f"{path}: {where} decompresses to {total} bytes but claims {size}: it is cut short or corrupt")
    return pieces[0] if len(pieces) == 1 else b"".join(pieces)


def _lz4_reader(data: memoryview) -> Any:
    """``read(n)`` over an LZ4 frame's output, as zstandard's stream reader gives (b"" at the end)."""
    decompressor = lz4.frame.LZ4FrameDecompressor()
    pending = [data]

    def read(n: int) -> bytes:
        if decompressor.eof:
            return b""
        return decompressor.decompress(pending.pop() if pending else b"", max_length=n)

    return read


def _chunk_records(body: memoryview, path: Path, where: str, index: ChunkIndex | None = None) -> bytes:
    """A chunk record's records (``body``: the record after its opcode and length), decompressed and checked:
    the compressed bytes against the record (they end it: writers put nothing after them, and a header zeroed
    by damage would otherwise read as an empty chunk), its header against its index in the summary (when
    given), the output against the claimed size and CRC."""
    if len(body) < _CHUNK_HEADER.size:
        raise BagDamaged(f"{path}: {where} is cut short")
    _start, _end, size, crc, name_length = _CHUNK_HEADER.unpack_from(body)
    pos = _CHUNK_HEADER.size + name_length
    if pos + 8 > len(body):
        raise BagDamaged(
            f"{path}: {where}: its compression name claims {name_length} bytes, the record holds "
            f"{len(body) - _CHUNK_HEADER.size - 8}"
        )
    compression = bytes(body[_CHUNK_HEADER.size : pos]).decode("latin-1")
    length = _U64.unpack_from(body, pos)[0]
    pos += 8
    if length != len(body) - pos:  # the data is the chunk's last field: a zeroed header would read as empty
        raise BagDamaged(f"{path}: {where} claims {length} compressed bytes, its record holds {len(body) - pos}")
    if index is not None and (compression, size) != (index.compression, index.uncompressed_size):
        raise BagDamaged(
            f"{path}: {where} says {compression!r}, {size} bytes; its index in the summary says "
            f"{index.compression!r}, {index.uncompressed_size} bytes"
        )
    records = _decompress(body[pos : pos + length], compression, size, path, where)
    if crc and zlib.crc32(records) != crc:
        raise BagDamaged(f"{path}: {where}: its CRC does not match: the data is corrupt")
    return records


def chunk_at(f: BinaryIO, size: int, index: ChunkIndex, path: Path) -> bytes:
    """The records of the chunk a chunk index points at, decompressed and checked. The index's length is the one
    used (the summary's CRC covers it; the record's own length field nothing): a chunk whose length field alone
    is damaged still reads, its content being checked against the index, its sizes and its CRC."""
    where = f"the chunk at byte {index.chunk_start_offset}"
    head = _read_at(f, size, index.chunk_start_offset, _RECORD_PREFIX, path, where)
    if head[0] != _OP_CHUNK or index.chunk_length < _RECORD_PREFIX:
        raise BagDamaged(f"{path}: the summary's index of {where} does not point at a chunk record")
    body = _read_at(
        f, size, index.chunk_start_offset + _RECORD_PREFIX, index.chunk_length - _RECORD_PREFIX, path, where
    )
    return _chunk_records(memoryview(body), path, where, index)


def message_data(
    records: bytes, wanted: Mapping[int, list[bytes]], channels: Mapping[int, Channel], path: Path, where: str
) -> None:
    """Append the data of each message record of ``records`` whose channel id is in ``wanted`` (every record
    checked to fit, every message to have its header and a channel of the summary). The scorer's hot loop."""
    unpack_u64, unpack_u16, wanted_get, header = _U64.unpack_from, _U16.unpack_from, wanted.get, _MESSAGE_HEADER.size
    pos, end = 0, len(records)
    try:
        while pos < end:
            body = pos + _RECORD_PREFIX
            stop = body + unpack_u64(records, pos + 1)[0]  # struct.error when the header is cut short
            if stop > end:
                raise BagDamaged(
                    f"{path}: {where}: the record at byte {pos} of its data claims {stop - body} "
                    f"bytes, {end - body} are left"
                )
            if records[pos] == _OP_MESSAGE:
                if stop - body < header:
                    raise BagDamaged(
                        f"{path}: {where}: the message at byte {pos} of its data is shorter than a message header"
                    )
                channel_id = unpack_u16(records, body)[0]
                into = wanted_get(channel_id)
                if into is not None:
                    into.append(records[body + header : stop])
                elif channel_id not in channels:
                    raise BagDamaged(
                        f"{path}: {where}: a message of channel {channel_id}, which the summary does not hold"
                    )
            pos = stop
    except struct.error:
        raise BagDamaged(f"{path}: {where}: the record at byte {pos} of its data is cut short") from None


def messages_in(
    records: bytes, channels: Mapping[int, Channel], path: Path, where: str
) -> Iterator[tuple[int, int, int, bytes]]:
    """``(record index, channel id, log time, data)`` of each message record of ``records`` (checked as in
    :func:`message_data`); the index counts every record, as mcap's reader orders messages of equal log time."""
    for i, (opcode, body, stop) in enumerate(_records(records, 0, len(records), path, where)):
        if opcode != _OP_MESSAGE:
            continue
        if stop - body < _MESSAGE_HEADER.size:
            raise BagDamaged(f"{path}: {where}: a message record is shorter than a message header")
        channel_id, _sequence, log_time, _publish = _MESSAGE_HEADER.unpack_from(records, body)
        if channel_id not in channels:
            raise BagDamaged(f"{path}: {where}: a message of channel {channel_id}, which the summary does not hold")
        yield i, channel_id, log_time, records[body + _MESSAGE_HEADER.size : stop]


class RecordScan:
    """The schemas, channels and messages of an MCAP file in file order, read from its start one record at a
    time and checked as the reader checks them (bench_engine.recovery rebuilds a bag from them: it needs no
    summary section).

    Iterating gives one list per top-level record: a chunk's schemas, channels and messages once the whole
    chunk has been read and checked, a schema, channel or message outside chunks alone (other records give
    nothing). It ends at the end of the data section (a DataEnd record, or the footer: :attr:`complete` is then
    True) or of the file, and raises :class:`BagDamaged` at the first damage: a record cut short, a length past
    the end of the file, a chunk that does not decompress or whose CRC does not match, a zeroed block, a record
    the data section does not hold (an opcode MCAP does not define there, private ones included: rosbag2 writes
    none) or whose inner lengths do not add up to its own (a chunk whose opcode a flipped bit made into a
    message index is damage, not a record to skip). :attr:`good` is the offset just after the last whole record
    read (0 until the magic has been read). It holds one record at a time."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        self.good = 0
        self.complete = False

    def __iter__(self) -> Iterator[list[Schema | Channel | Message]]:
        path = self.path
        with open(path, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            if size < len(_MAGIC) or _read_at(f, size, 0, len(_MAGIC), path, "the magic") != _MAGIC:
                raise BagDamaged(f"{path} is not an MCAP file (no MCAP magic at its start)")
            pos = self.good = len(_MAGIC)
            while pos < size:
                if pos + _RECORD_PREFIX > size:
                    raise BagDamaged(
                        f"{path}: the record at byte {pos} is cut short (the file ends "
                        f"{size - pos} bytes into its header)"
                    )
                head = _read_at(f, size, pos, _RECORD_PREFIX, path, "a record header")
                opcode, length = head[0], _U64.unpack_from(head, 1)[0]
                body = pos + _RECORD_PREFIX
                if length > size - body:
                    raise BagDamaged(
                        f"{path}: the record at byte {pos} claims {length} bytes, the file holds {size - body} more"
                    )
                if opcode not in _DATA_SECTION:
                    zeroed = " (a zeroed block?)" if not opcode else ""
                    raise BagDamaged(
                        f"{path}: the record at byte {pos} has opcode {opcode:#04x}, which the data "
                        f"section of an MCAP file does not hold{zeroed}"
                    )
                self._check_layout(f, size, opcode, pos, length)
                if opcode in (_OP_DATA_END, _OP_FOOTER):
                    self.good, self.complete = body + length, True
                    return
                items = self._items(f, size, opcode, pos, length)
                pos = self.good = body + length
                if items:
                    yield items

    def _check_layout(self, f: BinaryIO, size: int, opcode: int, pos: int, length: int) -> None:
        """The fixed sizes and length prefixes inside a record the scan does not parse add up to its length (the
        footer: 20 bytes, then the file's closing magic)."""

        def field(at: int, unpack: struct.Struct) -> int:
            if at + unpack.size > length:
                raise _Cut
            return unpack.unpack(_read_at(f, size, pos + _RECORD_PREFIX + at, unpack.size, self.path, "a field"))[0]

        try:
            if opcode == _OP_HEADER:  # profile, library
                name = field(0, _U32)
                ok = 8 + name + field(4 + name, _U32) == length
            elif opcode == _OP_MESSAGE_INDEX:  # channel id, then (log time, offset) pairs
                entries = field(2, _U32)
                ok = 6 + entries == length and entries % 16 == 0
            elif opcode == _OP_METADATA:  # name, map of strings
                name = field(0, _U32)
                ok = 8 + name + field(4 + name, _U32) == length
            elif opcode == _OP_ATTACHMENT:  # log and create time, name, media type, data, CRC
                name = field(16, _U32)
                media = field(20 + name, _U32)
                ok = 16 + 8 + name + media + 8 + field(24 + name + media, _U64) + 4 == length
            elif opcode == _OP_DATA_END:
                ok = length == 4
            elif opcode == _OP_FOOTER:
                ok = length == 20 and pos + _RECORD_PREFIX + length + len(_MAGIC) == size
            else:
                return
        except _Cut:
            ok = False
        if not ok:
            name = Opcode(opcode).name.lower().replace("_", " ")
            raise BagDamaged(
                f"{self.path}: the {name} record at byte {pos} is garbled (its fields do not fill its {length} bytes)"
            )

    def _items(self, f: BinaryIO, size: int, opcode: int, pos: int, length: int) -> list[Any]:
        """What one top-level record holds (only the records recovery needs are read at all)."""
        if opcode not in (_OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK):
            return []
        where = f"the {Opcode(opcode).name.lower()} record at byte {pos}"
        if length > MAX_RECORD_BYTES:
            raise BagDamaged(
                f"{self.path}: {where} claims {length} bytes, more than the reader's limit of "
                f"{MAX_RECORD_BYTES} (bench_engine.mcap_records.MAX_RECORD_BYTES)"
            )
        body = memoryview(_read_at(f, size, pos + _RECORD_PREFIX, length, self.path, where))
        if opcode != _OP_CHUNK:
            return [self._record(opcode, body, where)]
        records = _chunk_records(body, self.path, f"the chunk at byte {pos}")
        return [
            self._record(op, memoryview(records)[start:stop], f"{where}, its record at byte {start}")
            for op, start, stop in _records(records, 0, len(records), self.path, where)
            if op in (_OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE)
        ]

    def _record(self, opcode: int, body: memoryview, where: str) -> Schema | Channel | Message:
        if opcode == _OP_SCHEMA:
            return _parse(Schema, body, self.path, where)
        if opcode == _OP_CHANNEL:
            return _parse(Channel, body, self.path, where)
        if len(body) < _MESSAGE_HEADER.size:
            raise BagDamaged(f"{self.path}: {where} is shorter than a message header")
        channel_id, sequence, log_time, publish_time = _MESSAGE_HEADER.unpack_from(body)
        return Message(
            channel_id=channel_id,
            sequence=sequence,
            log_time=log_time,
            publish_time=publish_time,
            data=bytes(body[_MESSAGE_HEADER.size :]),
        )
