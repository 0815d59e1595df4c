"""The bag writer: a rosbag2 (Jazzy, MCAP storage) bag directory, as ``ros2 bag record -s mcap`` writes it.

Format (checked against rosbag2's ``jazzy`` branch):

* directory ``<dir>/`` with ``metadata.yaml`` (bench_engine.bag_metadata) and ``<dir>/<dirname>_0.mcap``;
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

Log times are the caller's (the recorder gives sim time: bench_engine.sim_clock); ``metadata.yaml``'s
``starting_time`` and ``duration`` are the least log time and the span to the greatest.

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
import os
import threading
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, BinaryIO

from mcap.writer import LIBRARY_IDENTIFIER, CompressionType, Writer

from bench_engine.bag_metadata import BagTopic, LogSpan, bag_information, dump_yaml, offered_qos, string_pairs
from bench_engine.msg_schema import schema_text, type_hash

CHUNK_SIZE = 768 * 1024
MAX_QUEUED = 20_000  # write() waits for the writer thread beyond this many queued messages
POLL_S = 0.005  # writer thread's idle wait
LIBRARY = f"bench_engine.bag_writer; {LIBRARY_IDENTIFIER}"
_FLUSH = object()  # writer-thread work item: end the chunk and flush the file


class FlushSchedule:
    """When a live recorder flushes its bag: at a step once ``steps`` steps and ``wall_s`` seconds of wall time
    (time.monotonic) have both passed since the last flush, or since the schedule was made (so the first flush
    comes after ``steps`` steps when recording started earlier). A killed recorder then loses at most the
    longer of the two, and a fast run's chunks stay few: a flush at every step of a lock-step run with long
    steps left ~17,000 chunks in a grace_velocity day, whose summary took longer to read than its messages.
    ``clock``: the wall clock in s."""

    def __init__(self, steps: int, wall_s: float, clock: Callable[[], float] = time.monotonic) -> None:
        if steps < 1 or not wall_s >= 0:
            raise ValueError(f"FlushSchedule needs steps >= 1 and wall_s >= 0, got {steps}, {wall_s}")
        self.steps, self.wall_s, self._clock = steps, wall_s, clock
        self._since = 0
        self._flushed_at = clock()

    def due(self) -> bool:
        """Count one step; True when the bag should be flushed now (the schedule then starts again)."""
        self._since += 1
        now = self._clock()
        if self._since < self.steps or now - self._flushed_at < self.wall_s:
            return False
        self._since, self._flushed_at = 0, now
        return True


class BagWriter:
    """Write a rosbag2 (Jazzy, MCAP storage) bag directory; see the module docstring for the format.

    ``directory`` is created (it may exist if empty); the MCAP file is ``<dirname>_0.mcap`` unless
    ``storage_name`` gives another file name. ``custom_data``: the metadata's string pairs (more with
    :meth:`set_custom_data` before closing). Usable as a context manager.
    """

    def __init__(
        self,
        directory: str | os.PathLike,
        storage_name: str | None = None,
        custom_data: Mapping[str, str] | None = None,
    ) -> None:
        self.directory = Path(directory)
        self.storage_name = storage_name or f"{self.directory.name}_0.mcap"
        self.mcap_path = self.directory / self.storage_name
        self.metadata_path = self.directory / "metadata.yaml"
        self.ros_distro = os.environ.get("ROS_DISTRO", "jazzy")
        self._custom_data = string_pairs(custom_data or {})
        self._topics: dict[str, BagTopic] = {}
        self._schemas: dict[str, int] = {}
        self._stats = LogSpan()
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
            topic = BagTopic(name, type_name, offered_qos(qos), type_hash(type_name))
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
        self._custom_data = {**self._custom_data, **string_pairs(items)}

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
            elif isinstance(item[0], BagTopic):
                self._register(*item)
            else:
                self._add_message(*item)
            drained = True
        return drained

    def _register(self, topic: BagTopic, definition: str) -> None:
        schema_id = self._schemas.get(topic.type_name)
        if schema_id is None:
            schema_id = self._mcap.register_schema(topic.type_name, "ros2msg", definition.encode("utf-8"))
            self._schemas[topic.type_name] = schema_id
        topic.channel_id = self._mcap.register_channel(
            topic.name,
            "cdr",
            schema_id,
            {"offered_qos_profiles": dump_yaml(topic.qos), "topic_type_hash": topic.type_hash},
        )

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
        """The bag metadata for the messages written so far."""
        return bag_information(
            list(self._topics.values()), self._stats, self.storage_name, self._custom_data, self.ros_distro
        )
