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
"""
from __future__ import annotations

import collections
import enum
import os
import struct
import sys
import threading
import time
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path, PurePath
from typing import Any, BinaryIO

import lz4.frame
import yaml
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.reader import make_reader
from mcap.records import Chunk
from mcap.summary import Summary
from mcap.writer import LIBRARY_IDENTIFIER, CompressionType, Writer

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


_RECORD_PREFIX = 1 + 8  # an MCAP record's opcode (uint8) and length (uint64)
_MESSAGE_HEADER = 2 + 4 + 8 + 8  # a message record's channel id, sequence, log time and publish time
_OPCODE_MESSAGE = 0x05
_U64, _U16 = struct.Struct("<Q"), struct.Struct("<H")


def _chunk_records(chunk: Chunk) -> bytes:
    """A chunk's records, decompressed."""
    if chunk.compression == "zstd":
        return zstandard.ZstdDecompressor().decompress(chunk.data, max_output_size=chunk.uncompressed_size)
    if chunk.compression == "lz4":
        return lz4.frame.decompress(chunk.data)
    if chunk.compression == "":
        return chunk.data
    raise BagDamaged(f"chunk compression {chunk.compression!r} is not one MCAP defines")


def _collect_messages(records: bytes, wanted: dict[int, list[bytes]]) -> None:
    """Append the data of each message record of ``records`` whose channel id is in ``wanted``."""
    pos, end = 0, len(records)
    while pos < end:
        body = pos + _RECORD_PREFIX
        pos = body + _U64.unpack_from(records, pos + 1)[0]
        if records[body - _RECORD_PREFIX] == _OPCODE_MESSAGE:
            into = wanted.get(_U16.unpack_from(records, body)[0])
            if into is not None:
                into.append(records[body + _MESSAGE_HEADER:pos])


class BagDamaged(ValueError):
    """A bag's MCAP file cannot be read as a whole (truncated or corrupt)."""


class BagReader:
    """Read a bag written by :class:`BagWriter` or rosbag2 (MCAP storage): a bag directory or a bare ``.mcap``."""

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
                info = yaml.safe_load(metadata.read_text(encoding="utf-8"))["rosbag2_bagfile_information"]
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
        """The summary section of one of the bag's files (read once)."""
        if path not in self._summaries:
            with open(path, "rb") as f:
                try:
                    summary = make_reader(f).get_summary()
                except Exception:  # noqa: BLE001 - a damaged summary section reads as none at all
                    summary = None
            if summary is None:
                raise BagDamaged(f"{path} has no summary section: the file is truncated; rebuild it with "
                                 f"scripts/recover_bag.py --force {self.path}")
            self._summaries[path] = summary
        return self._summaries[path]

    def topics(self) -> dict[str, str]:
        """Topic name -> type name (``pkg/msg/Type``)."""
        out: dict[str, str] = {}
        for path in self.files:
            summary = self._summary(path)
            for channel in summary.channels.values():
                out[channel.topic] = summary.schemas[channel.schema_id].name
        return out

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[tuple[str, str, int, bytes]]:
        """``(topic, type_name, log_time_ns, cdr_bytes)`` in log-time order within each file (sim-time order for
        the bench's bags; messages of equal log time in the order they were written)."""
        wanted = None if topics is None else list(topics)
        for path in self.files:
            with open(path, "rb") as f:
                for schema, channel, message in make_reader(f).iter_messages(topics=wanted):
                    yield channel.topic, schema.name, message.log_time, message.data

    def payloads(self, topics: Iterable[str]) -> dict[str, list[bytes]]:
        """Topic -> the CDR bytes of all its messages, in the order the recorder wrote them.

        Reads each chunk that holds one of ``topics`` whole and walks its message records directly:
        ``iter_messages`` builds a record object per message (and per message it skips), which was ~0.1 s of
        a leo_radar bag's 0.17 s load; this takes ~0.03 s. The chunk header is read with mcap's own record
        class, the chunk decompressed with the library mcap itself uses (zstd, lz4 or none)."""
        out: dict[str, list[bytes]] = {topic: [] for topic in topics}
        for path in self.files:
            summary = self._summary(path)
            wanted = {cid: out[ch.topic] for cid, ch in summary.channels.items() if ch.topic in out}
            with open(path, "rb") as f:
                for index in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
                    if wanted.keys().isdisjoint(index.message_index_offsets):
                        continue
                    f.seek(index.chunk_start_offset + _RECORD_PREFIX)
                    _collect_messages(_chunk_records(Chunk.read(ReadDataStream(f))), wanted)
        return {topic: data for topic, data in out.items() if data}

    def tables(self, topics: Iterable[str]) -> dict[str, Table]:
        """Topic -> all its messages as columns (bench_engine.columns), in the order the recorder wrote them."""
        types = self.topics()
        return {topic: table(types[topic], data) for topic, data in self.payloads(topics).items()}

    def decoded(self, topics: Iterable[str] | None = None) -> Iterator[tuple[str, int, Any]]:
        """``(topic, log_time_ns, message)`` deserialized into the generated ROS classes (no DDS needed)."""
        from rclpy.serialization import deserialize_message

        classes: dict[str, type] = {}
        for topic, type_name, log_ns, data in self.messages(topics):
            cls = classes.get(type_name)
            if cls is None:
                cls = classes[type_name] = message_class(type_name)
            yield topic, log_ns, deserialize_message(data, cls)
