"""Bags that survive a crash: rebuild a complete rosbag2 bag from what a killed recorder left on disk.

A recorder killed without running Python code (SIGKILL, a crash of the interpreter) leaves an MCAP file without
summary and footer, and no ``metadata.yaml``: readers refuse it. The recorder flushes a chunk at least every
second of sim time (bench_engine.recorder_node), so the file holds every chunk up to the last flush, then
perhaps a partial record. :func:`recover` reads the records in order up to the first incomplete one, and
writes a new, complete bag (MCAP with summary, ``metadata.yaml``) with every message it found, keeping the
damaged file as ``<name>.mcap.truncated``; it reports what it kept and what it could not read. Like
``ros2 bag reindex``, but for a file whose tail is missing.
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

    def summary(self) -> str:
        counts = ", ".join(f"{topic} {n}" for topic, n in sorted(self.kept.items()))
        kept_as = self.truncated_file.name if self.truncated_file else "-"
        return (f"{self.bag}: recovered {sum(self.kept.values())} messages ({counts}); {self.lost_bytes} bytes "
                f"after the last complete record were unreadable ({self.reason}); the damaged file is kept as "
                f"{kept_as}")


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
    writer = BagWriter(work, storage_name=path.name)
    for channel in sorted(channels.values(), key=lambda c: c.id):
        qos = yaml.safe_load(channel.metadata.get("offered_qos_profiles", "") or "null")
        writer.add_topic(channel.topic, schemas[channel.schema_id].name, qos)
    kept: dict[str, int] = {}
    for m in sorted(messages, key=lambda m: m.log_time):
        topic = channels[m.channel_id].topic
        writer.write(topic, m.data, m.log_time, m.publish_time)
        kept[topic] = kept.get(topic, 0) + 1
    writer.close()
    truncated = path.with_name(path.name + ".truncated")
    os.replace(path, truncated)
    os.replace(work / path.name, path)
    os.replace(work / "metadata.yaml", bag_dir / "metadata.yaml")
    shutil.rmtree(work)
    return Recovery(bag_dir, kept, lost, truncated, reason)


def ensure_complete(bag_dir: Path | str) -> Recovery | None:
    """Recover ``bag_dir`` if a crash left it without ``metadata.yaml``; None when it is complete."""
    return recover(bag_dir) if needs_recovery(Path(bag_dir)) else None

