"""Bags that survive a crash: rebuild a complete rosbag2 bag from what a killed recorder left on disk.

A recorder killed without running Python code (SIGKILL, a crash of the interpreter) leaves an MCAP file without
summary and footer, and no ``metadata.yaml``: readers refuse it. The recorder flushes a chunk at least every
second of sim time (bench_engine.recorder_node), so the file holds every chunk up to the last flush, then
perhaps a partial record. :func:`recover` reads the records in order up to the first incomplete one, and
writes a new, complete bag (MCAP with summary, ``metadata.yaml``) with every message it found, keeping the
damaged file as ``<name>.mcap.truncated``; it reports what it kept and what it could not read. Like
``ros2 bag reindex``, but for a file whose tail is missing.

Messages keep their log and publish times (sim time, bench_engine.bag.SimClock) and their order in the file:
log times are not monotonic across topics, and the rebuilt bag reads like one the recorder closed. A bag
rebuilt with ``--force`` keeps its ``metadata.yaml``'s ``custom_data`` (the recorder's wall-clock span).
"""
from __future__ import annotations

import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import yaml
from mcap.records import Channel, Message, Schema
from mcap.stream_reader import StreamReader

from bench_engine.bag import BagWriter


class BagUnrecoverable(ValueError):
    """The directory holds no MCAP file, or not even its header could be read."""


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
        span = (f", sim time {self.log_span_ns[0] * 1e-9:.9g}–{self.log_span_ns[1] * 1e-9:.9g} s"
                if self.log_span_ns else "")
        return (f"{self.bag}: recovered {sum(self.kept.values())} messages ({counts}{span}); {self.lost_bytes} "
                f"bytes after the last complete record were unreadable ({self.reason}); the damaged file is "
                f"kept as {kept_as}")


def needs_recovery(bag_dir: Path) -> bool:
    """A bag directory whose MCAP file exists but whose ``metadata.yaml`` does not (a recorder that died)."""
    bag_dir = Path(bag_dir)
    return bag_dir.is_dir() and not (bag_dir / "metadata.yaml").exists() and any(bag_dir.glob("*.mcap"))


def _read_records(path: Path) -> tuple[dict, dict, list, int, str]:
    """(schemas, channels, messages, bytes read, why it stopped) from the start of an MCAP file."""
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    messages: list[Message] = []
    size = path.stat().st_size
    with open(path, "rb") as f:
        reader = StreamReader(f, record_size_limit=size)
        good = 0
        reason = "the file ends in a complete footer"
        try:
            for record in reader.records:
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels[record.id] = record
                elif isinstance(record, Message):
                    messages.append(record)
                good = f.tell()
        except Exception as err:  # noqa: BLE001 - whatever the damage, the readable part ends here
            reason = f"{type(err).__name__} at the end of the written data"
        if good == 0 and not schemas:
            raise BagUnrecoverable(f"{path}: not even the MCAP header could be read ({reason})")
    return schemas, channels, messages, max(0, size - good), reason


def _custom_data(bag_dir: Path) -> dict[str, str]:
    """The ``custom_data`` of the bag's ``metadata.yaml``, if it has one, as strings (YAML written by yaml-cpp
    leaves a number-like string unquoted)."""
    metadata = bag_dir / "metadata.yaml"
    if not metadata.is_file():
        return {}
    info = yaml.safe_load(metadata.read_text(encoding="utf-8")) or {}
    custom = (info.get("rosbag2_bagfile_information") or {}).get("custom_data") or {}
    return {str(key): str(value) for key, value in custom.items()}


def _log_span(messages: list[Message]) -> tuple[int, int] | None:
    """The least and the greatest log time of ``messages`` (None for none)."""
    log_times = [m.log_time for m in messages]
    return (min(log_times), max(log_times)) if log_times else None


def recover(bag_dir: Path | str) -> Recovery:
    """Rebuild ``bag_dir`` (a bag directory with a damaged or summary-less MCAP file) in place."""
    bag_dir = Path(bag_dir)
    files = sorted(p for p in bag_dir.glob("*.mcap"))
    if not files:
        raise BagUnrecoverable(f"{bag_dir}: no .mcap file to recover")
    path = files[0]
    schemas, channels, messages, lost, reason = _read_records(path)
    work = bag_dir.with_name(bag_dir.name + ".recovering")
    shutil.rmtree(work, ignore_errors=True)
    writer = BagWriter(work, storage_name=path.name, custom_data=_custom_data(bag_dir))
    for channel in sorted(channels.values(), key=lambda c: c.id):
        qos = yaml.safe_load(channel.metadata.get("offered_qos_profiles", "") or "null")
        writer.add_topic(channel.topic, schemas[channel.schema_id].name, qos)
    kept: dict[str, int] = {}
    for m in messages:  # in file order, as the recorder wrote them
        topic = channels[m.channel_id].topic
        writer.write(topic, m.data, m.log_time, m.publish_time)
        kept[topic] = kept.get(topic, 0) + 1
    writer.close()
    truncated = path.with_name(path.name + ".truncated")
    os.replace(path, truncated)
    os.replace(work / path.name, path)
    os.replace(work / "metadata.yaml", bag_dir / "metadata.yaml")
    shutil.rmtree(work)
    return Recovery(bag_dir, kept, lost, truncated, reason, _log_span(messages))


def ensure_complete(bag_dir: Path | str) -> Recovery | None:
    """Recover ``bag_dir`` if a crash left it without ``metadata.yaml``; None when it is complete."""
    return recover(bag_dir) if needs_recovery(Path(bag_dir)) else None

