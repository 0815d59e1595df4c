"""rosbag2-compatible MCAP bags: a writer producing what ``ros2 bag record -s mcap`` writes (Jazzy), and a reader.

Format (checked against rosbag2's ``jazzy`` branch):

* directory ``<dir>/`` with ``metadata.yaml`` (``rosbag2_bagfile_information``, version 9, as
  ``rosbag2_storage/include/rosbag2_storage/yaml.hpp`` encodes it) and ``<dir>/<dirname>_0.mcap``;
* MCAP profile ``ros2``; one schema per type, named ``pkg/msg/Type``, encoding ``ros2msg``, data
  :func:`bench_engine.msg_schema.schema_text`; one channel per topic, message encoding ``cdr``, channel metadata
  ``offered_qos_profiles`` (YAML text of the QoS list, version-9 string enums) and ``topic_type_hash``
  (``rosbag2_storage_mcap/src/mcap_storage.cpp::create_topic``);
* a metadata record ``rosbag2`` with the single key ``serialized_metadata`` (the YAML of the bag metadata,
  without the ``rosbag2_bagfile_information`` wrapper), written once when the bag opens and again, final,
  at close (``SequentialWriter::open`` / ``close`` -> ``MCAPStorage::update_metadata``);
* chunks of 768 KiB (the MCAP C++ writer's default, which rosbag2 keeps), zstd-compressed as with the
  rosbag2 storage presets ``zstd_fast`` / ``zstd_small`` (plain rosbag2 defaults to no compression);
* ``custom_data`` (rosbag2's ``ros2 bag record --custom-data``): string keys and values, or ``~`` when empty.

Log times are sim time (:class:`SimClock`, the recorder's rule): a message's log and publish times are its
``header.stamp``, the clock's own time for ``rosgraph_msgs/Clock``, and otherwise the latest ``/clock`` (what
``ros2 bag record --use-sim-time`` gives every message). Messages are written as they arrive, so within a
chunk log times are not monotonic across topics (an estimate of step k may follow the truth of step k+3).
MCAP allows that: chunk indexes and statistics hold each chunk's and the file's least and greatest log time,
message index entries are in write order, and readers that return log-time order sort (mcap, rosbags);
``metadata.yaml``'s ``starting_time`` and ``duration`` are the least log time and the span to the greatest.

Shutdown safety: all MCAP work happens on a writer thread. :meth:`BagWriter.write` only appends to a deque
(atomic, lock-free), so :meth:`BagWriter.close` may be called from a SIGINT/SIGTERM handler at any moment,
even one that then raises ``SystemExit``: the thread drains what was queued, writes the summary and footer,
fsyncs, and writes ``metadata.yaml`` (atomically). If the main thread ends without ``close()``, the writer
thread closes the bag itself. A truncated file (no summary) is left only when the process dies without running
Python code: SIGKILL, ``os._exit``, or SIGTERM with neither a Python handler nor rclpy's (``rclpy.init``
installs C-level SIGINT/SIGTERM handlers that turn the signal into a context shutdown; a recorder then
closes the bag once spinning returns). :meth:`BagWriter.flush` ends the current chunk and hands it to the
operating system, so such a crash loses only what came after the last flush; bench_engine.recovery then
rebuilds a complete bag from the chunks on disk.

Reading: :class:`BagReader` reads MCAP records itself and trusts no length, offset or size in the file (the
comment above :data:`MAX_CHUNK_BYTES`); whatever is wrong with a bag ends in one of the readers' own errors
(bench_engine.bag_errors: :class:`BagDamaged`, :class:`MessageDamaged`, :class:`BagUnsupported`, all
:class:`BagError`), one line naming the file and what is wrong. tests/test_fuzz_readers.py fuzzes it.
"""
from __future__ import annotations

import collections
import contextlib
import enum
import heapq
import io
import os
import struct
import sys
import threading
import time
import zlib
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path, PurePath
from typing import Any, BinaryIO

import lz4.frame
import yaml
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import AttachmentIndex, Channel, ChunkIndex, Message, MetadataIndex, Schema, Statistics
from mcap.summary import Summary
from mcap.writer import LIBRARY_IDENTIFIER, CompressionType, Writer

from bench_engine import yamlio
from bench_engine.bag_errors import BagDamaged, BagError, BagUnsupported, MessageDamaged  # noqa: F401 - re-exported
from bench_engine.columns import Table, table
from bench_engine.msg_schema import canonical_type_name, message_class, schema_text, type_hash

METADATA_VERSION = 9
STORAGE_IDENTIFIER = "mcap"
CHUNK_SIZE = 768 * 1024
MAX_QUEUED = 20_000          # write() waits for the writer thread beyond this many queued messages
POLL_S = 0.005               # writer thread's idle wait (≈ 0.3 % of a core while idle)
NS_MAX = 2**63 - 1           # rosbag2's starting time of a bag without messages (nanoseconds::max)
LIBRARY = f"bench_engine.bag; {LIBRARY_IDENTIFIER}"
_FLUSH = object()            # writer-thread work item: end the chunk and flush the file

DEFAULT_QOS: dict[str, Any] = {
    # What a reliable keep-last publisher offers, as rosbag2 stores it: durations and liveliness as the
    # graph reports them for a default publisher (infinite, automatic).
    "history": "keep_last",
    "depth": 1000,
    "reliability": "reliable",
    "durability": "volatile",
    "deadline": NS_MAX,
    "lifespan": NS_MAX,
    "liveliness": "automatic",
    "liveliness_lease_duration": NS_MAX,
    "avoid_ros_namespace_conventions": False,
}
_POLICIES = {
    "history": {"system_default", "keep_last", "keep_all", "unknown"},
    "reliability": {"system_default", "reliable", "best_effort", "unknown", "best_available"},
    "durability": {"system_default", "transient_local", "volatile", "unknown", "best_available"},
    "liveliness": {"system_default", "automatic", "manual_by_topic", "unknown", "best_available"},
}


class _Rosbag2Dumper(yaml.SafeDumper):
    """YAML in yaml-cpp's style: nested block sequences indented, ``""`` for empty strings, ``~`` for null,
    repeated values written out (no anchors)."""

    def ignore_aliases(self, data: Any) -> bool:
        return True

    def increase_indent(self, flow: bool = False, indentless: bool = False) -> None:
        super().increase_indent(flow, False)


_Rosbag2Dumper.add_representer(type(None), lambda d, _: d.represent_scalar("tag:yaml.org,2002:null", "~"))
_Rosbag2Dumper.add_representer(
    str, lambda d, s: d.represent_scalar("tag:yaml.org,2002:str", s, style='"' if s == "" else None))


def dump_yaml(data: Any) -> str:
    """YAML text as rosbag2 (yaml-cpp ``YAML::Dump``) writes it: key order kept, no trailing newline."""
    return yaml.dump(data, Dumper=_Rosbag2Dumper, sort_keys=False, width=float("inf")).rstrip("\n")


def _field(profile: Any, key: str) -> Any:
    """A QoS field of a dict or of an object with attributes (e.g. ``rclpy.qos.QoSProfile``)."""
    if isinstance(profile, Mapping):
        return profile.get(key, DEFAULT_QOS[key])
    return getattr(profile, key, DEFAULT_QOS[key])


def _policy(key: str, value: Any) -> str:
    """A policy as rmw's string name: accepts the name or an enum member (rclpy's ``HistoryPolicy.KEEP_ALL``)."""
    name = getattr(value, "name", value)
    name = str(name).lower()
    if name not in _POLICIES[key]:
        raise ValueError(f"QoS {key} must be one of {sorted(_POLICIES[key])}, got {value!r}")
    return name


def _duration(value: Any) -> dict[str, int]:
    """rmw_time_t {sec, nsec} from int nanoseconds, a {sec, nsec} dict or an rclpy Duration."""
    if isinstance(value, Mapping):
        return {"sec": int(value["sec"]), "nsec": int(value["nsec"])}
    sec, nsec = divmod(int(getattr(value, "nanoseconds", value)), 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


def qos_dict(profile: Any = None) -> dict[str, Any]:
    """One QoS profile in rosbag2's version-9 layout; missing fields come from :data:`DEFAULT_QOS`."""
    profile = {} if profile is None else profile
    if isinstance(profile, Mapping) and not set(profile) <= set(DEFAULT_QOS):
        raise ValueError(f"unknown QoS keys {sorted(set(profile) - set(DEFAULT_QOS))}")
    depth = int(_field(profile, "depth"))
    if depth < 0:
        raise ValueError(f"QoS depth must be >= 0, got {depth}")
    return {
        "history": _policy("history", _field(profile, "history")),
        "depth": depth,
        "reliability": _policy("reliability", _field(profile, "reliability")),
        "durability": _policy("durability", _field(profile, "durability")),
        "deadline": _duration(_field(profile, "deadline")),
        "lifespan": _duration(_field(profile, "lifespan")),
        "liveliness": _policy("liveliness", _field(profile, "liveliness")),
        "liveliness_lease_duration": _duration(_field(profile, "liveliness_lease_duration")),
        "avoid_ros_namespace_conventions": bool(_field(profile, "avoid_ros_namespace_conventions")),
    }


def offered_qos(qos: Any = None) -> list[dict[str, Any]]:
    """The offered QoS list of a topic: ``None`` (default), one profile, or one profile per publisher."""
    if isinstance(qos, Sequence) and not isinstance(qos, (str, bytes)):
        return [qos_dict(p) for p in qos]
    return [qos_dict(qos)]


# --- log times in sim time ---------------------------------------------------------------------------------

CLOCK_TYPE = "rosgraph_msgs/msg/Clock"
HEADER_TYPE = "std_msgs/Header"  # as a generated class names a field's type
STAMP_AT = 4
"""Byte offset of a leading ``std_msgs/Header``'s stamp (and of a Clock's ``clock``): right after the CDR
encapsulation header, a ``builtin_interfaces/Time`` {int32 sec, uint32 nanosec}, 4-aligned."""
_TIME_BY_ENCAPSULATION = {b"\x00\x01": struct.Struct("<iI"), b"\x00\x00": struct.Struct(">iI")}  # plain CDR LE, BE


class StampRule(enum.Enum):
    """Where a topic's log times come from (:func:`stamp_rule`)."""

    CLOCK = "clock"                 # rosgraph_msgs/Clock: its own time, which also sets the latest clock
    HEADER = "header"               # first field a std_msgs/Header: header.stamp
    LATEST_CLOCK = "latest clock"   # anything else: the latest clock received


def stamp_rule(type_name: str) -> StampRule:
    """The rule for messages of ``type_name``, from its generated class's fields: any type whose first field is
    a ``std_msgs/Header`` (bench messages, nav_msgs/Odometry, diagnostic_msgs/DiagnosticArray, …) is
    :attr:`StampRule.HEADER`; ``rosgraph_msgs/Clock`` is :attr:`StampRule.CLOCK`; every other type (e.g.
    visualization_msgs/MarkerArray, std_msgs/String) :attr:`StampRule.LATEST_CLOCK`."""
    if canonical_type_name(type_name) == CLOCK_TYPE:
        return StampRule.CLOCK
    first = next(iter(message_class(type_name).get_fields_and_field_types().values()), None)
    return StampRule.HEADER if first == HEADER_TYPE else StampRule.LATEST_CLOCK


def leading_stamp_ns(data: bytes) -> int | None:
    """The ``builtin_interfaces/Time`` a message's CDR bytes open with, in ns, read in place (no
    deserialisation). None when the bytes cannot hold it (shorter than 12 bytes), are not plain CDR (XCDR1,
    little or big endian: what ROS 2's rmw write), or hold no valid time from 0 on (an MCAP log time is
    unsigned; ``nanosec`` must be below 10⁹)."""
    if len(data) < STAMP_AT + 8:
        return None
    time_struct = _TIME_BY_ENCAPSULATION.get(bytes(data[:2]))
    if time_struct is None:
        return None
    sec, nanosec = time_struct.unpack_from(data, STAMP_AT)
    return sec * 1_000_000_000 + nanosec if sec >= 0 and nanosec < 1_000_000_000 else None


class SimClock:
    """Sim-time log times for a recorder, decided per topic when it is declared (:func:`stamp_rule`).

    Contract: a message's log time is its ``header.stamp`` when its type opens with a ``std_msgs/Header``,
    the ``clock`` of a ``rosgraph_msgs/Clock``, and otherwise the latest clock received (``start_ns`` before
    the first: what ``ros2 bag record --use-sim-time`` gives every message); the same when a stamp cannot be
    read (:func:`leading_stamp_ns`: short, not plain CDR, not a valid time). A clock that cannot be read does
    not move it."""

    def __init__(self, start_ns: int) -> None:
        self.now_ns = int(start_ns)
        self._rules: dict[str, StampRule] = {}

    def add_topic(self, topic: str, type_name: str) -> None:
        """Decide the rule of ``topic``'s log times from its type."""
        self._rules[topic] = stamp_rule(type_name)

    def log_time_ns(self, topic: str, data: bytes) -> int:
        """The sim-time log time of one message of a declared topic."""
        rule = self._rules[topic]
        stamp_ns = None if rule is StampRule.LATEST_CLOCK else leading_stamp_ns(data)
        if stamp_ns is None:
            return self.now_ns
        if rule is StampRule.CLOCK:
            self.now_ns = stamp_ns
        return stamp_ns


# --- writer ------------------------------------------------------------------------------------------------

@dataclass
class _Topic:
    name: str
    type_name: str
    qos: list[dict[str, Any]]
    type_hash: str
    channel_id: int = 0
    count: int = 0


@dataclass
class _Stats:
    count: int = 0
    first_ns: int = NS_MAX
    last_ns: int = -1

    def add(self, log_time_ns: int) -> None:
        self.count += 1
        self.first_ns = min(self.first_ns, log_time_ns)
        self.last_ns = max(self.last_ns, log_time_ns)

    @property
    def duration_ns(self) -> int:
        return self.last_ns - self.first_ns if self.count else 0


def _string_pairs(items: Mapping[str, str]) -> dict[str, str]:
    """``items`` checked to be rosbag2 custom data: a map of strings to strings."""
    bad = {k: v for k, v in items.items() if not (isinstance(k, str) and isinstance(v, str))}
    if bad:
        raise TypeError(f"custom data maps strings to strings, got {bad!r}")
    return dict(items)


class BagWriter:
    """Write a rosbag2 (Jazzy, MCAP storage) bag directory; see the module docstring for the format.

    ``directory`` is created (it may exist if empty); the MCAP file is ``<dirname>_0.mcap`` unless
    ``storage_name`` gives another file name. ``custom_data``: the metadata's string pairs (more with
    :meth:`set_custom_data` before closing). Usable as a context manager.
    """

    def __init__(self, directory: str | os.PathLike, storage_name: str | None = None,
                 custom_data: Mapping[str, str] | None = None) -> None:
        self.directory = Path(directory)
        self.storage_name = storage_name or f"{self.directory.name}_0.mcap"
        self.mcap_path = self.directory / self.storage_name
        self.metadata_path = self.directory / "metadata.yaml"
        self.ros_distro = os.environ.get("ROS_DISTRO", "jazzy")
        self._custom_data = _string_pairs(custom_data or {})
        self._topics: dict[str, _Topic] = {}
        self._schemas: dict[str, int] = {}
        self._stats = _Stats()
        self._pending: collections.deque = collections.deque()  # writer-thread work, in call order
        self._topics_lock = threading.Lock()
        self._closing = False
        self._error: BaseException | None = None
        self._file = self._create()
        self._mcap = Writer(self._file, chunk_size=CHUNK_SIZE, compression=CompressionType.ZSTD)
        self._mcap.start(profile="ros2", library=LIBRARY)
        self._write_metadata_record()
        self._thread = threading.Thread(target=self._run, name=f"bag-writer:{self.directory.name}")
        self._thread.start()

    def _create(self) -> BinaryIO:
        self.directory.mkdir(parents=True, exist_ok=True)
        if any(self.directory.iterdir()):
            raise FileExistsError(f"bag directory {self.directory} already exists and is not empty")
        return open(self.mcap_path, "xb")

    @property
    def closed(self) -> bool:
        return self._closing

    def add_topic(self, name: str, type_name: str, qos: Any = None) -> None:
        """Declare a topic. ``qos``: a dict (keys ``history``, ``depth``, ``reliability``, ``durability``, and
        optionally ``deadline``/``lifespan``/``liveliness_lease_duration`` in ns, ``liveliness``,
        ``avoid_ros_namespace_conventions``), an ``rclpy.qos.QoSProfile``, or a list of them (one per
        publisher); ``None`` means :data:`DEFAULT_QOS`. Re-declaring a topic with the same type is a no-op."""
        self._check_open()
        with self._topics_lock:
            known = self._topics.get(name)
            if known is not None:
                if known.type_name != type_name:
                    raise ValueError(f"topic {name} already declared with type {known.type_name}")
                return
            topic = _Topic(name, type_name, offered_qos(qos), type_hash(type_name))
            definition = schema_text(type_name)
            self._topics[name] = topic
            self._pending.append((topic, definition))

    def write(self, topic: str, data: bytes, log_time_ns: int, publish_time_ns: int | None = None) -> None:
        """Queue one CDR-serialized message (``rclpy.serialization.serialize_message`` or a raw subscription)."""
        self._check_open()
        if topic not in self._topics:
            raise KeyError(f"unknown topic {topic!r}: call add_topic() first")
        payload = data if type(data) is bytes else bytes(data)
        log_ns = int(log_time_ns)
        pub_ns = log_ns if publish_time_ns is None else int(publish_time_ns)
        while len(self._pending) > MAX_QUEUED and self._thread.is_alive():
            time.sleep(POLL_S)
        self._pending.append((topic, payload, log_ns, pub_ns))

    def set_custom_data(self, items: Mapping[str, str]) -> None:
        """Add (or replace) ``custom_data`` pairs of the final metadata (rosbag2's map of strings)."""
        self._check_open()
        self._custom_data = {**self._custom_data, **_string_pairs(items)}

    def flush(self, wait: bool = False) -> None:
        """End the chunk in progress and write it to the file (asynchronously, in call order): what a crash
        of this process loses is then only what is written after this call. With ``wait`` the call returns
        once the writer thread has handed that chunk to the operating system, i.e. once the file on disk holds
        every message written before the call (for a reader or a copy of the file while it is written; the
        recorder does not wait)."""
        self._check_open()
        if not wait:
            self._pending.append((_FLUSH,))
            return
        done = threading.Event()
        self._pending.append((_FLUSH, done))
        while not done.wait(10 * POLL_S) and self._thread.is_alive():
            pass
        self._raise_error()

    def close(self) -> None:
        """Finish the bag: drain queued messages, write the MCAP summary and ``metadata.yaml``. Idempotent and
        safe to call from a signal handler."""
        self._closing = True
        if threading.current_thread() is not self._thread:
            self._thread.join()
        self._raise_error()

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def _check_open(self) -> None:
        self._raise_error()
        if self._closing:
            raise ValueError(f"bag {self.directory} is closed")

    def _raise_error(self) -> None:
        if self._error is not None:
            raise RuntimeError(f"writing bag {self.directory} failed") from self._error

    # --- writer thread ---------------------------------------------------------------------------------

    def _run(self) -> None:
        try:
            while True:
                stopping = self._closing or not threading.main_thread().is_alive()
                drained = self._drain()
                if stopping:
                    break
                if not drained:
                    time.sleep(POLL_S)
            self._closing = True
            self._finish()
        except BaseException as error:  # reported to the caller by close() / write()
            self._error = error
            self._closing = True
            self._file.close()

    def _drain(self) -> bool:
        items = self._pending
        drained = False
        while items:
            item = items.popleft()
            if item[0] is _FLUSH:
                self._mcap.flush()
                self._file.flush()
                if len(item) > 1:
                    item[1].set()  # flush(wait=True) returns
            elif isinstance(item[0], _Topic):
                self._register(*item)
            else:
                self._add_message(*item)
            drained = True
        return drained

    def _register(self, topic: _Topic, definition: str) -> None:
        schema_id = self._schemas.get(topic.type_name)
        if schema_id is None:
            schema_id = self._mcap.register_schema(topic.type_name, "ros2msg", definition.encode("utf-8"))
            self._schemas[topic.type_name] = schema_id
        topic.channel_id = self._mcap.register_channel(
            topic.name, "cdr", schema_id,
            {"offered_qos_profiles": dump_yaml(topic.qos), "topic_type_hash": topic.type_hash})

    def _add_message(self, name: str, data: bytes, log_ns: int, pub_ns: int) -> None:
        topic = self._topics[name]
        self._mcap.add_message(topic.channel_id, log_time=log_ns, data=data, publish_time=pub_ns, sequence=0)
        topic.count += 1
        self._stats.add(log_ns)

    def _finish(self) -> None:
        self._write_metadata_record()
        self._mcap.finish()
        self._file.flush()
        os.fsync(self._file.fileno())
        self._file.close()
        tmp = self.metadata_path.with_suffix(".yaml.tmp")
        tmp.write_text(dump_yaml({"rosbag2_bagfile_information": self._metadata()}), encoding="utf-8")
        os.replace(tmp, self.metadata_path)

    def _write_metadata_record(self) -> None:
        self._mcap.add_metadata("rosbag2", {"serialized_metadata": dump_yaml(self._metadata())})

    def _metadata(self) -> dict[str, Any]:
        """The bag metadata (rosbag2 ``BagMetadata``, version 9) for the messages written so far."""
        stats = self._stats
        start = {"nanoseconds_since_epoch": stats.first_ns}
        duration = {"nanoseconds": stats.duration_ns}
        topics = [{
            "topic_metadata": {
                "name": t.name,
                "type": t.type_name,
                "serialization_format": "cdr",
                "offered_qos_profiles": t.qos,
                "type_description_hash": t.type_hash,
            },
            "message_count": t.count,
        } for t in list(self._topics.values()) if t.channel_id]
        return {
            "version": METADATA_VERSION,
            "storage_identifier": STORAGE_IDENTIFIER,
            "duration": duration,
            "starting_time": start,
            "message_count": stats.count,
            "topics_with_message_count": topics,
            "compression_format": "",
            "compression_mode": "",
            "relative_file_paths": [self.storage_name],
            "files": [{"path": self.storage_name, "starting_time": start, "duration": duration,
                       "message_count": stats.count}],
            "custom_data": dict(self._custom_data) or None,
            "ros_distro": self.ros_distro,
        }


# --- reader ------------------------------------------------------------------------------------------------
#
# The reader walks MCAP records itself, defensively: a damaged or hostile file (tests/test_fuzz_readers.py) ends
# in a BagError naming the file and what is wrong (bench_engine.bag_errors), never in a library's error, a hang
# or an allocation its bytes do not justify. Every offset and length is checked against the bytes that are
# there (the file's size, the record's, the chunk's) before it is used; a chunk's claimed uncompressed size
# against MAX_CHUNK_BYTES before anything is decompressed, and the output grows only with the data really there
# (in reads of at most _PIECE bytes, never past the claim); CRCs are checked where the file has them (summary,
# chunks), so a flipped bit reads as damage, not as other numbers.

MAX_CHUNK_BYTES = 1 << 30
"""The largest uncompressed chunk the reader accepts. rosbag2 and :class:`BagWriter` write chunks of 768 KiB; a
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
_OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK = (int(Opcode.SCHEMA), int(Opcode.CHANNEL), int(Opcode.MESSAGE),
                                                   int(Opcode.CHUNK))
_OP_FOOTER, _OP_DATA_END = int(Opcode.FOOTER), int(Opcode.DATA_END)
_OP_HEADER, _OP_MESSAGE_INDEX = int(Opcode.HEADER), int(Opcode.MESSAGE_INDEX)
_OP_METADATA, _OP_ATTACHMENT = int(Opcode.METADATA), int(Opcode.ATTACHMENT)
_DATA_SECTION = {_OP_HEADER, _OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK, _OP_MESSAGE_INDEX, _OP_ATTACHMENT,
                 _OP_METADATA, _OP_DATA_END, _OP_FOOTER}  # what a scan from the start may meet
_SUMMARY_RECORDS = {int(Opcode.SCHEMA): Schema, int(Opcode.CHANNEL): Channel, int(Opcode.CHUNK_INDEX): ChunkIndex,
                    int(Opcode.STATISTICS): Statistics, int(Opcode.METADATA_INDEX): MetadataIndex,
                    int(Opcode.ATTACHMENT_INDEX): AttachmentIndex}
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
        return bytes(self._body[start:self._count])


def _parse(record_class: type, body: bytes | memoryview, path: Path, what: str) -> Any:
    """A record of ``record_class`` (mcap.records) parsed from its body, which must hold it."""
    try:
        return record_class.read(_RecordBody(body))
    except (_Cut, UnicodeDecodeError, struct.error):
        raise BagDamaged(f"{path}: {what} is cut short or garbled") from None


def _read_at(f: BinaryIO, size: int, offset: int, length: int, path: Path, what: str) -> bytes:
    """``length`` bytes of the file at ``offset``, refused unless the file (``size`` bytes) holds them."""
    if offset < 0 or length < 0 or offset + length > size:
        raise BagDamaged(f"{path}: {what} at byte {offset} claims {length} bytes, past the end of the file "
                         f"({size} bytes)")
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
            raise BagDamaged(f"{path}: {where}: the record at byte {pos} claims {stop - body} bytes, "
                             f"{end - body} are left")
        yield buf[pos], body, stop
        pos = stop


def _read_summary(f: BinaryIO, size: int, path: Path, rebuild: str) -> Summary:
    """The summary section of an MCAP file (schemas, channels, chunk indexes, statistics), checked: magic at both
    ends, the footer, the summary CRC, every record fitting, and the indexes against the data section."""
    if size < 2 * len(_MAGIC) + _FOOTER.size:
        raise BagDamaged(f"{path} holds {size} bytes, too few for an MCAP file: it is truncated{rebuild}")
    if _read_at(f, size, 0, len(_MAGIC), path, "the magic") != _MAGIC:
        raise BagDamaged(f"{path} is not an MCAP file (no MCAP magic at its start)")
    footer_at = size - len(_MAGIC) - _FOOTER.size
    tail = _read_at(f, size, footer_at, _FOOTER.size + len(_MAGIC), path, "the footer")
    opcode, length, start, _offsets, crc = _FOOTER.unpack_from(tail)
    footer_ok = tail[_FOOTER.size:] == _MAGIC and opcode == _OP_FOOTER and length == _FOOTER.size - _RECORD_PREFIX
    if not footer_ok or not start:
        raise BagDamaged(f"{path} has no summary section: the file is truncated{rebuild}")
    if not len(_MAGIC) <= start <= footer_at:
        raise BagDamaged(f"{path}: the footer puts the summary at byte {start}, outside the file{rebuild}")
    if footer_at - start > MAX_SUMMARY_BYTES:
        raise BagDamaged(f"{path}: the footer puts the summary at byte {start}, {footer_at - start} bytes before "
                         f"it: more than the reader's limit of {MAX_SUMMARY_BYTES} (bench_engine.bag."
                         f"MAX_SUMMARY_BYTES){rebuild}")
    data = _read_at(f, size, start, footer_at - start, path, "the summary section")
    if crc and zlib.crc32(tail[:_FOOTER.size - 4], zlib.crc32(data)) != crc:
        raise BagDamaged(f"{path}: the summary section's CRC does not match: it is corrupt{rebuild}")
    summary = Summary()
    for opcode, body, stop in _records(data, 0, len(data), path, "the summary section"):
        record_class = _SUMMARY_RECORDS.get(opcode)
        if record_class is None:
            continue
        record = _parse(record_class, memoryview(data)[body:stop], path,
                        f"the summary's {record_class.__name__} record at byte {start + body - _RECORD_PREFIX}")
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
            raise BagDamaged(f"{path}: channel {channel.topic!r} names schema {channel.schema_id}, which the summary "
                             f"does not hold{rebuild}")
    for index in summary.chunk_indexes:
        where = f"the summary's index of a chunk at byte {index.chunk_start_offset}"
        if index.chunk_start_offset < len(_MAGIC) or index.chunk_start_offset + index.chunk_length > data_end:
            raise BagDamaged(f"{path}: {where} ({index.chunk_length} bytes) points outside the data section"
                             f"{rebuild}")
        if index.chunk_length > MAX_RECORD_BYTES:
            raise BagDamaged(f"{path}: {where} claims {index.chunk_length} bytes, more than the reader's limit of "
                             f"{MAX_RECORD_BYTES} (bench_engine.bag.MAX_RECORD_BYTES)")
        if index.compression not in _COMPRESSIONS:
            raise BagDamaged(f"{path}: {where}: compression {index.compression!r} is not one MCAP defines")
        if index.uncompressed_size > MAX_CHUNK_BYTES:
            raise BagDamaged(f"{path}: {where} claims {index.uncompressed_size} bytes uncompressed, more than the "
                             f"reader's limit of {MAX_CHUNK_BYTES} (bench_engine.bag.MAX_CHUNK_BYTES)")
        unknown = set(index.message_index_offsets) - set(summary.channels)
        if unknown:
            raise BagDamaged(f"{path}: {where} lists channel(s) {sorted(unknown)}, which the summary does not hold"
                             f"{rebuild}")


def _decompress(data: memoryview, compression: str, size: int, path: Path, where: str) -> bytes:
    """A chunk's ``data`` decompressed, which must give exactly the ``size`` bytes the chunk claims. The claim is
    checked against :data:`MAX_CHUNK_BYTES` first, and the output read in pieces of at most :data:`_PIECE`
    bytes (at once when one zstd frame claims the same size, no more than that), so what is allocated follows
    the data really there, whatever the claim or the frame header says."""
    if size > MAX_CHUNK_BYTES:
        raise BagDamaged(f"{path}: {where} claims {size} bytes uncompressed, more than the reader's limit of "
                         f"{MAX_CHUNK_BYTES} (bench_engine.bag.MAX_CHUNK_BYTES)")
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
        raise BagDamaged(f"{path}: {where} decompresses to {total} bytes but claims {size}: it is cut short or "
                         f"corrupt")
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
        raise BagDamaged(f"{path}: {where}: its compression name claims {name_length} bytes, the record holds "
                         f"{len(body) - _CHUNK_HEADER.size - 8}")
    compression = bytes(body[_CHUNK_HEADER.size:pos]).decode("latin-1")
    length = _U64.unpack_from(body, pos)[0]
    pos += 8
    if length != len(body) - pos:  # the data is the chunk's last field: a zeroed header would read as empty
        raise BagDamaged(f"{path}: {where} claims {length} compressed bytes, its record holds {len(body) - pos}")
    if index is not None and (compression, size) != (index.compression, index.uncompressed_size):
        raise BagDamaged(f"{path}: {where} says {compression!r}, {size} bytes; its index in the summary says "
                         f"{index.compression!r}, {index.uncompressed_size} bytes")
    records = _decompress(body[pos:pos + length], compression, size, path, where)
    if crc and zlib.crc32(records) != crc:
        raise BagDamaged(f"{path}: {where}: its CRC does not match: the data is corrupt")
    return records


def _chunk_at(f: BinaryIO, size: int, index: ChunkIndex, path: Path) -> bytes:
    """The records of the chunk a chunk index points at, decompressed and checked. The index's length is the one
    used (the summary's CRC covers it; the record's own length field nothing): a chunk whose length field alone
    is damaged still reads, its content being checked against the index, its sizes and its CRC."""
    where = f"the chunk at byte {index.chunk_start_offset}"
    head = _read_at(f, size, index.chunk_start_offset, _RECORD_PREFIX, path, where)
    if head[0] != _OP_CHUNK or index.chunk_length < _RECORD_PREFIX:
        raise BagDamaged(f"{path}: the summary's index of {where} does not point at a chunk record")
    body = _read_at(f, size, index.chunk_start_offset + _RECORD_PREFIX, index.chunk_length - _RECORD_PREFIX, path,
                    where)
    return _chunk_records(memoryview(body), path, where, index)


def _message_data(records: bytes, wanted: Mapping[int, list[bytes]], channels: Mapping[int, Channel],
                  path: Path, where: str) -> None:
    """Append the data of each message record of ``records`` whose channel id is in ``wanted`` (every record
    checked to fit, every message to have its header and a channel of the summary). The scorer's hot loop."""
    unpack_u64, unpack_u16, wanted_get, header = _U64.unpack_from, _U16.unpack_from, wanted.get, _MESSAGE_HEADER.size
    pos, end = 0, len(records)
    try:
        while pos < end:
            body = pos + _RECORD_PREFIX
            stop = body + unpack_u64(records, pos + 1)[0]  # struct.error when the header is cut short
            if stop > end:
                raise BagDamaged(f"{path}: {where}: the record at byte {pos} of its data claims {stop - body} "
                                 f"bytes, {end - body} are left")
            if records[pos] == _OP_MESSAGE:
                if stop - body < header:
                    raise BagDamaged(f"{path}: {where}: the message at byte {pos} of its data is shorter than a "
                                     f"message header")
                channel_id = unpack_u16(records, body)[0]
                into = wanted_get(channel_id)
                if into is not None:
                    into.append(records[body + header:stop])
                elif channel_id not in channels:
                    raise BagDamaged(f"{path}: {where}: a message of channel {channel_id}, which the summary does "
                                     f"not hold")
            pos = stop
    except struct.error:
        raise BagDamaged(f"{path}: {where}: the record at byte {pos} of its data is cut short") from None


def _messages_in(records: bytes, channels: Mapping[int, Channel], path: Path, where: str
                 ) -> Iterator[tuple[int, int, int, bytes]]:
    """``(record index, channel id, log time, data)`` of each message record of ``records`` (checked as in
    :func:`_message_data`); the index counts every record, as mcap's reader orders messages of equal log time."""
    for i, (opcode, body, stop) in enumerate(_records(records, 0, len(records), path, where)):
        if opcode != _OP_MESSAGE:
            continue
        if stop - body < _MESSAGE_HEADER.size:
            raise BagDamaged(f"{path}: {where}: a message record is shorter than a message header")
        channel_id, _sequence, log_time, _publish = _MESSAGE_HEADER.unpack_from(records, body)
        if channel_id not in channels:
            raise BagDamaged(f"{path}: {where}: a message of channel {channel_id}, which the summary does not hold")
        yield i, channel_id, log_time, records[body + _MESSAGE_HEADER.size:stop]


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
                    raise BagDamaged(f"{path}: the record at byte {pos} is cut short (the file ends "
                                     f"{size - pos} bytes into its header)")
                head = _read_at(f, size, pos, _RECORD_PREFIX, path, "a record header")
                opcode, length = head[0], _U64.unpack_from(head, 1)[0]
                body = pos + _RECORD_PREFIX
                if length > size - body:
                    raise BagDamaged(f"{path}: the record at byte {pos} claims {length} bytes, the file holds "
                                     f"{size - body} more")
                if opcode not in _DATA_SECTION:
                    zeroed = " (a zeroed block?)" if not opcode else ""
                    raise BagDamaged(f"{path}: the record at byte {pos} has opcode {opcode:#04x}, which the data "
                                     f"section of an MCAP file does not hold{zeroed}")
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
            raise BagDamaged(f"{self.path}: the {name} record at byte {pos} is garbled (its fields do not fill its "
                             f"{length} bytes)")

    def _items(self, f: BinaryIO, size: int, opcode: int, pos: int, length: int) -> list[Any]:
        """What one top-level record holds (only the records recovery needs are read at all)."""
        if opcode not in (_OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK):
            return []
        where = f"the {Opcode(opcode).name.lower()} record at byte {pos}"
        if length > MAX_RECORD_BYTES:
            raise BagDamaged(f"{self.path}: {where} claims {length} bytes, more than the reader's limit of "
                             f"{MAX_RECORD_BYTES} (bench_engine.bag.MAX_RECORD_BYTES)")
        body = memoryview(_read_at(f, size, pos + _RECORD_PREFIX, length, self.path, where))
        if opcode != _OP_CHUNK:
            return [self._record(opcode, body, where)]
        records = _chunk_records(body, self.path, f"the chunk at byte {pos}")
        return [self._record(op, memoryview(records)[start:stop], f"{where}, its record at byte {start}")
                for op, start, stop in _records(records, 0, len(records), self.path, where)
                if op in (_OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE)]

    def _record(self, opcode: int, body: memoryview, where: str) -> Schema | Channel | Message:
        if opcode == _OP_SCHEMA:
            return _parse(Schema, body, self.path, where)
        if opcode == _OP_CHANNEL:
            return _parse(Channel, body, self.path, where)
        if len(body) < _MESSAGE_HEADER.size:
            raise BagDamaged(f"{self.path}: {where} is shorter than a message header")
        channel_id, sequence, log_time, publish_time = _MESSAGE_HEADER.unpack_from(body)
        return Message(channel_id=channel_id, sequence=sequence, log_time=log_time, publish_time=publish_time,
                       data=bytes(body[_MESSAGE_HEADER.size:]))


class BagReader:
    """Read a bag written by :class:`BagWriter` or rosbag2 (MCAP storage): a bag directory or a bare ``.mcap``.
    A damaged or hostile bag raises :class:`BagError` (bench_engine.bag_errors) from any method; what an intact
    part of a file holds reads as written (CRCs are checked where the file has them)."""

    def __init__(self, path: str | os.PathLike, recover: bool = True) -> None:
        """``recover``: rebuild a bag directory a crashed recorder left without metadata.yaml first
        (bench_engine.recovery), saying so on stderr."""
        self.path = Path(path)
        if recover:
            from bench_engine.recovery import ensure_complete
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
                raise BagDamaged(f"{metadata} is not rosbag2 metadata{where}: rebuild it with "
                                 f"scripts/recover_bag.py --force {self.path}") from err
            if storage != STORAGE_IDENTIFIER:
                raise BagDamaged(f"{self.path}: storage {storage!r} is not mcap")
            files = [self.path / PurePath(str(p)).name for p in relative]
            missing = [f.name for f in files if not f.is_file()]
            if missing or not files:
                raise BagDamaged(f"{self.path}: metadata.yaml names {', '.join(missing) or 'no file'}, which is "
                                 "not there: the bag is incomplete (copy its .mcap file too)")
            return files
        files = sorted(self.path.glob("*.mcap"))
        if not files:
            raise FileNotFoundError(f"no metadata.yaml or .mcap file in {self.path}")
        return files

    def _summary(self, path: Path) -> Summary:
        """The summary section of one of the bag's files (read once, checked: :func:`_read_summary`)."""
        if path not in self._summaries:
            with open(path, "rb") as f:
                size = os.fstat(f.fileno()).st_size
                self._summaries[path] = _read_summary(f, size, path, self._rebuild)
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
            raise BagDamaged(f"{err}; scripts/recover_bag.py --force {self.path} rebuilds the bag from what comes "
                             f"before it") from None

    @staticmethod
    def _chunks(f: BinaryIO, path: Path, summary: Summary, channels: Iterable[int]) -> Iterator[tuple[bytes, str]]:
        """``(records, where)`` of each indexed chunk of one file in file order that may hold a message of
        ``channels`` (a chunk without message indexes may hold any), decompressed and checked."""
        size = os.fstat(f.fileno()).st_size
        wanted = set(channels)
        for index in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
            if index.message_index_offsets and wanted.isdisjoint(index.message_index_offsets):
                continue
            yield _chunk_at(f, size, index, path), f"the chunk at byte {index.chunk_start_offset}"

    @staticmethod
    def _unindexed(path: Path, summary: Summary) -> Iterator[Message]:
        """The messages of a file whose summary indexes no chunks, in file order (its data section read from the
        start, as recovery reads it: :class:`RecordScan`), each of a channel the summary holds."""
        for records in RecordScan(path):
            for record in records:
                if isinstance(record, Message):
                    if record.channel_id not in summary.channels:
                        raise BagDamaged(f"{path}: a message of channel {record.channel_id}, which the summary "
                                         f"does not hold")
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
            channels = {cid: (ch.topic, summary.schemas[ch.schema_id].name if ch.schema_id else "")
                        for cid, ch in summary.channels.items() if wanted is None or ch.topic in wanted}
            if not channels:
                continue
            if not summary.chunk_indexes:  # no index: read in file order, then sort (mcap does the same)
                found = [(m.log_time, *channels[m.channel_id], m.data) for m in self._unindexed(path, summary)
                         if m.channel_id in channels]
                for log_time, topic, type_name, data in sorted(found, key=lambda m: m[0]):
                    yield topic, type_name, log_time, data
                continue
            with open(path, "rb") as f, self._salvage():
                yield from self._merged(f, path, summary, channels)

    def _merged(self, f: BinaryIO, path: Path, summary: Summary, channels: dict[int, tuple[str, str]]
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
            for i, cid, log_time, data in _messages_in(_chunk_at(f, size, item, path), summary.channels, path,
                                                       where):
                if cid in channels:
                    heapq.heappush(heap, ((log_time, item.chunk_start_offset, i), serial,
                                          (*channels[cid], log_time, data)))
                    serial += 1

    def payloads(self, topics: Iterable[str]) -> dict[str, list[bytes]]:
        """Topic -> the CDR bytes of all its messages, in the order the recorder wrote them.

        Reads each chunk that holds one of ``topics`` whole and walks its message records directly:
        ``iter_messages`` builds a record object per message (and per message it skips), which was ~0.1 s of
        a leo_radar bag's 0.17 s load; this takes ~0.03 s. Every record is checked to fit before it is read
        (module comment above :data:`MAX_CHUNK_BYTES`)."""
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
                    _message_data(records, wanted, summary.channels, path, where)
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
        from rclpy.serialization import deserialize_message

        classes: dict[str, type] = {}
        for topic, type_name, log_ns, data in self.messages(topics):
            cls = classes.get(type_name)
            if cls is None:
                try:
                    cls = classes[type_name] = message_class(type_name)
                except (ImportError, LookupError, AttributeError, ValueError) as err:
                    raise BagUnsupported(f"{self.path}: {topic}: message type {type_name!r} cannot be loaded "
                                         f"({err})") from None
            try:
                message = deserialize_message(data, cls)
            except Exception as err:  # noqa: BLE001 - rclpy's RMWError, or whatever its C deserialiser raises
                reason = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
                raise MessageDamaged(f"{self.path}: {topic}: the message at log time {log_ns} ns is not a "
                                     f"{type_name} ({reason})") from None
            yield topic, log_ns, message
