"""The bag reader: rosbag2 bags (MCAP storage) written by bench_engine.bag_writer or by rosbag2, a bag directory
or a bare ``.mcap`` file.

:class:`BagReader` reads MCAP records itself and trusts no length, offset or size in the file
(bench_engine.mcap_records); whatever is wrong with a bag ends in one of the readers' own errors
(bench_engine.bag_errors: :class:`BagDamaged`, :class:`MessageDamaged`, :class:`BagUnsupported`, all
:class:`BagError`), one line naming the file and what is wrong. A bag directory a crashed recorder left
without ``metadata.yaml`` is rebuilt first (bench_engine.recovery). tests/test_fuzz_readers.py fuzzes it.
"""

from __future__ import annotations

import contextlib
import heapq
import os
import sys
from collections.abc import Iterable, Iterator
from pathlib import Path, PurePath
from typing import Any, BinaryIO

import yaml
from mcap.records import ChunkIndex, Message
from mcap.summary import Summary

from bench_engine import yamlio
from bench_engine.bag_errors import BagDamaged, BagError, BagUnsupported, MessageDamaged
from bench_engine.bag_metadata import STORAGE_IDENTIFIER
from bench_engine.columns import Table, table
from bench_engine.mcap_records import RecordScan, chunk_at, message_data, messages_in, read_summary
from bench_engine.msg_schema import message_class
from bench_engine.recovery import ensure_complete


class BagReader:
    """Read a bag written by :class:`BagWriter` or rosbag2 (MCAP storage): a bag directory or a bare ``.mcap``.
    A damaged or hostile bag raises :class:`BagError` (bench_engine.bag_errors) from any method; what an intact
    part of a file holds reads as written (CRCs are checked where the file has them)."""

    def __init__(self, path: str | os.PathLike, recover: bool = True) -> None:
        """``recover``: rebuild a bag directory a crashed recorder left without metadata.yaml first
        (bench_engine.recovery), saying so on stderr."""
        self.path = Path(path)
        if recover:
            done = ensure_complete(self.path)
            if done is not None:
                print(f"[bag] {done.summary()}", file=sys.stderr)
        self.files = self._mcap_files()
        self._summaries: dict[Path, Summary] = {}

    def _mcap_files(self) -> list[Path]:
        if self.path.is_file():
            return [self.path]
        metadata = self.path / "metadata.yaml"
        if metadata.is_file():
            try:
                info = yamlio.load(metadata.read_text(encoding="utf-8"))["rosbag2_bagfile_information"]
                storage, relative = info["storage_identifier"], list(info["relative_file_paths"])
            except (yaml.YAMLError, UnicodeDecodeError, LookupError, TypeError) as err:
                mark = getattr(err, "problem_mark", None)
                where = f" (line {mark.line + 1})" if mark is not None else ""
                raise BagDamaged(
                    f"{metadata} is not rosbag2 metadata{where}: rebuild it with "
                    f"scripts/recover_bag.py --force {self.path}"
                ) from err
            if storage != STORAGE_IDENTIFIER:
                raise BagDamaged(f"{self.path}: storage {storage!r} is not mcap")
            files = [self.path / PurePath(str(p)).name for p in relative]
            missing = [f.name for f in files if not f.is_file()]
            if missing or not files:
                raise BagDamaged(
                    f"{self.path}: metadata.yaml names {', '.join(missing) or 'no file'}, which is "
                    "not there: the bag is incomplete (copy its .mcap file too)"
                )
            return files
        files = sorted(self.path.glob("*.mcap"))
        if not files:
            raise FileNotFoundError(f"no metadata.yaml or .mcap file in {self.path}")
        return files

    def _summary(self, path: Path) -> Summary:
        """The summary section of one of the bag's files (read once, checked: :func:`read_summary`)."""
        if path not in self._summaries:
            with open(path, "rb") as f:
                size = os.fstat(f.fileno()).st_size
                self._summaries[path] = read_summary(f, size, path, self._rebuild)
        return self._summaries[path]

    @property
    def _rebuild(self) -> str:
        return f"; rebuild it with scripts/recover_bag.py --force {self.path}"

    @contextlib.contextmanager
    def _salvage(self) -> Iterator[None]:
        """A damaged chunk's error says what to do: recovery keeps what comes before it."""
        try:
            yield
        except BagDamaged as err:
            if type(err) is not BagDamaged:
                raise
            raise BagDamaged(
                f"{err}; scripts/recover_bag.py --force {self.path} rebuilds the bag from what comes before it"
            ) from None

    @staticmethod
    def _chunks(f: BinaryIO, path: Path, summary: Summary, channels: Iterable[int]) -> Iterator[tuple[bytes, str]]:
        """``(records, where)`` of each indexed chunk of one file in file order that may hold a message of
        ``channels`` (a chunk without message indexes may hold any), decompressed and checked."""
        size = os.fstat(f.fileno()).st_size
        wanted = set(channels)
        for index in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
            if index.message_index_offsets and wanted.isdisjoint(index.message_index_offsets):
                continue
            yield chunk_at(f, size, index, path), f"the chunk at byte {index.chunk_start_offset}"

    @staticmethod
    def _unindexed(path: Path, summary: Summary) -> Iterator[Message]:
        """The messages of a file whose summary indexes no chunks, in file order (its data section read from the
        start, as recovery reads it: :class:`RecordScan`), each of a channel the summary holds."""
        for records in RecordScan(path):
            for record in records:
                if isinstance(record, Message):
                    if record.channel_id not in summary.channels:
                        raise BagDamaged(
                            f"{path}: a message of channel {record.channel_id}, which the summary does not hold"
                        )
                    yield record

    def topics(self) -> dict[str, str]:
        """Topic name -> type name (``pkg/msg/Type``)."""
        out: dict[str, str] = {}
        for path in self.files:
            summary = self._summary(path)
            for channel in summary.channels.values():
                if not channel.schema_id:
                    raise BagUnsupported(f"{path}: topic {channel.topic} has no schema: not a rosbag2 bag")
                out[channel.topic] = summary.schemas[channel.schema_id].name
        return out

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[tuple[str, str, int, bytes]]:
        """``(topic, type_name, log_time_ns, cdr_bytes)`` in log-time order within each file (sim-time order for
        the bench's bags; messages of equal log time in the order they were written), as mcap's reader orders
        them: the chunks by their first log time, each chunk's messages merged in as it is read."""
        wanted = None if topics is None else set(topics)
        for path in self.files:
            summary = self._summary(path)
            channels = {
                cid: (ch.topic, summary.schemas[ch.schema_id].name if ch.schema_id else "")
                for cid, ch in summary.channels.items()
                if wanted is None or ch.topic in wanted
            }
            if not channels:
                continue
            if not summary.chunk_indexes:  # no index: read in file order, then sort (mcap does the same)
                found = [
                    (m.log_time, *channels[m.channel_id], m.data)
                    for m in self._unindexed(path, summary)
                    if m.channel_id in channels
                ]
                for log_time, topic, type_name, data in sorted(found, key=lambda m: m[0]):
                    yield topic, type_name, log_time, data
                continue
            with open(path, "rb") as f, self._salvage():
                yield from self._merged(f, path, summary, channels)

    def _merged(
        self, f: BinaryIO, path: Path, summary: Summary, channels: dict[int, tuple[str, str]]
    ) -> Iterator[tuple[str, str, int, bytes]]:
        """Messages of indexed chunks in log-time order: a heap of chunks (by first log time) and of the messages
        of the chunks read so far; ties by chunk offset, then by record index in the chunk (mcap's order)."""
        size = os.fstat(f.fileno()).st_size
        heap: list[tuple[tuple[int, int, int], int, Any]] = []
        for n, index in enumerate(summary.chunk_indexes):
            if not index.message_index_offsets or not channels.keys().isdisjoint(index.message_index_offsets):
                heap.append(((index.message_start_time, index.chunk_start_offset, -1), n, index))
        heapq.heapify(heap)
        serial = len(heap)
        while heap:
            _key, _, item = heapq.heappop(heap)
            if not isinstance(item, ChunkIndex):
                yield item
                continue
            where = f"the chunk at byte {item.chunk_start_offset}"
            for i, cid, log_time, data in messages_in(chunk_at(f, size, item, path), summary.channels, path, where):
                if cid in channels:
                    heapq.heappush(
                        heap, ((log_time, item.chunk_start_offset, i), serial, (*channels[cid], log_time, data))
                    )
                    serial += 1

    def payloads(self, topics: Iterable[str]) -> dict[str, list[bytes]]:
        """Topic -> the CDR bytes of all its messages, in the order the recorder wrote them.

        Reads each chunk that holds one of ``topics`` whole and walks its message records directly, building no
        record object per message (mcap's ``iter_messages`` builds one per message, and per message it skips:
        most of a bag's load time). Every record is checked to fit before it is read (bench_engine.mcap_records)."""
        out: dict[str, list[bytes]] = {topic: [] for topic in topics}
        for path in self.files:
            summary = self._summary(path)
            wanted = {cid: out[ch.topic] for cid, ch in summary.channels.items() if ch.topic in out}
            if not wanted:
                continue
            if not summary.chunk_indexes:
                for message in self._unindexed(path, summary):
                    if message.channel_id in wanted:
                        wanted[message.channel_id].append(message.data)
                continue
            with open(path, "rb") as f, self._salvage():
                for records, where in self._chunks(f, path, summary, wanted):
                    message_data(records, wanted, summary.channels, path, where)
        return {topic: data for topic, data in out.items() if data}

    def tables(self, topics: Iterable[str]) -> dict[str, Table]:
        """Topic -> all its messages as columns (bench_engine.columns), in the order the recorder wrote them.
        A message that is not of its topic's type raises :class:`MessageDamaged` naming the bag and topic."""
        types = self.topics()
        out: dict[str, Table] = {}
        for topic, data in self.payloads(topics).items():
            try:
                out[topic] = table(types[topic], data)
            except BagError as err:
                raise type(err)(f"{self.path}: {topic}: {err}") from None
        return out

    def decoded(self, topics: Iterable[str] | None = None) -> Iterator[tuple[str, int, Any]]:
        """``(topic, log_time_ns, message)`` deserialized into the generated ROS classes (no DDS needed). A message
        whose bytes rclpy refuses raises :class:`MessageDamaged`; a type that is not installed,
        :class:`BagUnsupported`."""
        from rclpy.serialization import deserialize_message  # rclpy: scoring reads columns, not ROS messages

        classes: dict[str, type] = {}
        for topic, type_name, log_ns, data in self.messages(topics):
            cls = classes.get(type_name)
            if cls is None:
                try:
                    cls = classes[type_name] = message_class(type_name)
                except (ImportError, LookupError, AttributeError, ValueError) as err:
                    raise BagUnsupported(
                        f"{self.path}: {topic}: message type {type_name!r} cannot be loaded ({err})"
                    ) from None
            try:
                message = deserialize_message(data, cls)
            except Exception as err:  # noqa: BLE001 - rclpy's RMWError, or whatever its C deserialiser raises
                reason = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
                raise MessageDamaged(
                    f"{self.path}: {topic}: the message at log time {log_ns} ns is not a {type_name} ({reason})"
                ) from None
            yield topic, log_ns, message
