"""Bags that survive a crash: rebuild a complete rosbag2 bag from what a killed recorder left on disk.

A recorder killed without running Python code (SIGKILL, a crash of the interpreter) leaves an MCAP file without
summary and footer, and no ``metadata.yaml``: readers refuse it. The recorder flushes a chunk at least every
second of sim time (bench_engine.recorder_node), so the file holds every chunk up to the last flush, then
perhaps a partial record. :func:`recover` reads the records in order up to the first incomplete or damaged one
(bench_engine.mcap_records.RecordScan: every length checked against the file, every chunk decompressed within its
claimed
size and checked against its CRC), and writes a new, complete bag (MCAP with summary, ``metadata.yaml``) with
every message it found, keeping the damaged file as ``<name>.mcap.truncated``; it reports what it kept and what
it could not read. Like ``ros2 bag reindex``, but for a file whose tail is missing.

It streams: each chunk's messages go to the new bag's writer as soon as the chunk is read, and it waits for
the writer whenever :data:`WAIT_BYTES` of messages are queued, so what it holds is about one chunk of the old
file and a few of the new one, whatever the size of the bag (tests/test_recovery.py measures it).

Messages keep their log and publish times (sim time, bench_engine.sim_clock) and their order in the file:
log times are not monotonic across topics, and the rebuilt bag reads like one the recorder closed. A bag
rebuilt with ``--force`` keeps its ``metadata.yaml``'s ``custom_data`` (the recorder's wall-clock span).

Errors (bench_engine.bag_errors): :class:`BagUnrecoverable` when there is nothing to rebuild from (no MCAP
file, not even its magic), :class:`BagUnsupported` for a topic whose type is not installed; damage past the
magic only ends what is recovered (:attr:`Recovery.reason` says what it was).
"""

from __future__ import annotations

import functools
import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from mcap.records import Channel, Schema

from bench_engine import yamlio
from bench_engine.bag_errors import BagDamaged, BagUnrecoverable, BagUnsupported
from bench_engine.bag_writer import CHUNK_SIZE, BagWriter
from bench_engine.mcap_records import RecordScan

WAIT_BYTES = 4 * CHUNK_SIZE
"""Message bytes handed to the new bag's writer before :func:`recover` waits for it to write them."""


@dataclass
class Recovery:
    """What :func:`recover` did: messages kept per topic, bytes it could not read, the damaged file's name."""

    bag: Path
    kept: dict[str, int] = field(default_factory=dict)
    lost_bytes: int = 0
    truncated_file: Path | None = None
    reason: str = ""
    log_span_ns: tuple[int, int] | None = None  # least and greatest log time (sim time) kept

    def summary(self) -> str:
        counts = ", ".join(f"{topic} {n}" for topic, n in sorted(self.kept.items()))
        kept_as = self.truncated_file.name if self.truncated_file else "-"
        span = (
            f", sim time {self.log_span_ns[0] * 1e-9:.9g}–{self.log_span_ns[1] * 1e-9:.9g} s"
            if self.log_span_ns
            else ""
        )
        return (
            f"{self.bag}: recovered {sum(self.kept.values())} messages ({counts}{span}); {self.lost_bytes} "
            f"bytes after the last complete record were unreadable ({self.reason}); the damaged file is "
            f"kept as {kept_as}"
        )


def needs_recovery(bag_dir: Path) -> bool:
    """A bag directory whose MCAP file exists but whose ``metadata.yaml`` does not (a recorder that died)."""
    bag_dir = Path(bag_dir)
    return bag_dir.is_dir() and not (bag_dir / "metadata.yaml").exists() and any(bag_dir.glob("*.mcap"))


def _custom_data(bag_dir: Path) -> dict[str, str]:
    """The ``custom_data`` of the bag's ``metadata.yaml``, if it has one, as strings (YAML written by yaml-cpp
    leaves a number-like string unquoted); none when the file cannot be read (a forced rebuild of a bag whose
    metadata is damaged)."""
    metadata = bag_dir / "metadata.yaml"
    if not metadata.is_file():
        return {}
    try:
        info = yamlio.load(metadata.read_text(encoding="utf-8")) or {}
        custom = (info.get("rosbag2_bagfile_information") or {}).get("custom_data") or {}
        return {str(key): str(value) for key, value in custom.items()}
    except (yaml.YAMLError, UnicodeDecodeError, AttributeError):
        return {}


def _qos(channel: Channel) -> Any:
    """The channel's offered QoS profiles as rosbag2 stored them, or None (the default) when they cannot be read."""
    return _parsed_qos(channel.metadata.get("offered_qos_profiles", ""))


@functools.lru_cache(maxsize=64)
def _parsed_qos(text: str) -> Any:
    """QoS YAML text parsed (with libyaml: the pure-Python parser took most of a recovery); channels mostly share
    one text, so it is parsed once."""
    try:
        return yamlio.load(text or "null")
    except yaml.YAMLError:
        return None


class _Rebuild:
    """The new bag, written as the old file's records are read."""

    def __init__(self, writer: BagWriter, path: Path) -> None:
        self.writer, self.path = writer, path
        self.schemas: dict[int, Schema] = {}
        self.topics: dict[int, str] = {}
        self.kept: dict[str, int] = {}
        self.span: tuple[int, int] | None = None
        self.queued = 0

    def add(self, record: Any) -> None:
        if isinstance(record, Schema):
            self.schemas[record.id] = record
        elif isinstance(record, Channel):
            self._channel(record)
        else:
            topic = self.topics.get(record.channel_id)
            if topic is None:
                raise BagDamaged(
                    f"{self.path}: a message of channel {record.channel_id}, which no channel record before it declares"
                )
            self.writer.write(topic, record.data, record.log_time, record.publish_time)
            self.kept[topic] = self.kept.get(topic, 0) + 1
            t = record.log_time
            self.span = (t, t) if self.span is None else (min(self.span[0], t), max(self.span[1], t))
            self.queued += len(record.data)

    def _channel(self, channel: Channel) -> None:
        if channel.id in self.topics:
            return
        schema = self.schemas.get(channel.schema_id)
        if schema is None:
            raise BagDamaged(
                f"{self.path}: channel {channel.topic!r} names schema {channel.schema_id}, which no "
                f"schema record before it declares"
            )
        for qos in (_qos(channel), None):  # profiles the writer refuses are damage: the default instead
            try:
                self.writer.add_topic(channel.topic, schema.name, qos)
                break
            except (LookupError, OSError, ImportError) as err:  # the type is not installed
                raise BagUnsupported(
                    f"{self.path}: topic {channel.topic} has type {schema.name!r}, which is not installed: {err}"
                ) from None
            except (ValueError, TypeError, AttributeError) as err:
                if qos is None:
                    raise BagUnsupported(
                        f"{self.path}: topic {channel.topic} of type {schema.name!r} cannot be rebuilt: {err}"
                    ) from None
        self.topics[channel.id] = channel.topic

    def settle(self) -> None:
        """Wait for the writer once enough is queued: memory stays at a few chunks."""
        if self.queued >= WAIT_BYTES:
            self.writer.flush(wait=True)
            self.queued = 0


def _without_path(err: Exception, path: Path) -> str:
    text = str(err)
    return text[len(f"{path}: ") :] if text.startswith(f"{path}: ") else text


def recover(bag_dir: Path | str) -> Recovery:
    """Rebuild ``bag_dir`` (a bag directory with a damaged or summary-less MCAP file) in place, streaming."""
    bag_dir = Path(bag_dir)
    files = sorted(p for p in bag_dir.glob("*.mcap"))
    if not files:
        raise BagUnrecoverable(f"{bag_dir}: no .mcap file to recover")
    path = files[0]
    size = path.stat().st_size
    scan = RecordScan(path)
    work = bag_dir.with_name(bag_dir.name + ".recovering")
    shutil.rmtree(work, ignore_errors=True)
    writer = BagWriter(work, storage_name=path.name, custom_data=_custom_data(bag_dir))
    rebuild = _Rebuild(writer, path)
    reason = "the file ends in a complete footer"
    try:
        try:
            for records in scan:  # one chunk (or one record) at a time, in file order
                for record in records:
                    rebuild.add(record)
                rebuild.settle()
        except BagDamaged as err:
            if scan.good == 0:
                raise BagUnrecoverable(
                    f"{path}: not even the MCAP header could be read ({_without_path(err, path)})"
                ) from None
            reason = _without_path(err, path)
        else:
            if not scan.complete:
                reason = "the file ends after its last whole record"
        writer.close()
    except BaseException:
        writer.close()
        shutil.rmtree(work, ignore_errors=True)
        raise
    truncated = path.with_name(path.name + ".truncated")
    os.replace(path, truncated)
    os.replace(work / path.name, path)
    os.replace(work / "metadata.yaml", bag_dir / "metadata.yaml")
    shutil.rmtree(work)
    lost = 0 if scan.complete else max(0, size - scan.good)
    return Recovery(bag_dir, rebuild.kept, lost, truncated, reason, rebuild.span)


def ensure_complete(bag_dir: Path | str) -> Recovery | None:
    """Recover ``bag_dir`` if a crash left it without ``metadata.yaml``; None when it is complete."""
    return recover(bag_dir) if needs_recovery(Path(bag_dir)) else None
