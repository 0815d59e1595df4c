"""Log times in sim time: the recorder's rule for a message's log and publish times.

A message's log time is its ``header.stamp``, the clock's own time for ``rosgraph_msgs/Clock``, and otherwise
the latest ``/clock`` (what ``ros2 bag record --use-sim-time`` gives every message), so rosbag2 tools play a run
on its own time line. Messages are written as they arrive, so within a chunk log times are not monotonic
across topics (an estimate of step k may follow the truth of step k+3). MCAP allows that: chunk indexes and
statistics hold each chunk's and the file's least and greatest log time, message index entries are in write
order, and readers that return log-time order sort (mcap, rosbags).
"""

from __future__ import annotations

import enum
import struct

from bench_engine.msg_schema import canonical_type_name, message_class

CLOCK_TYPE = "rosgraph_msgs/msg/Clock"
HEADER_TYPE = "std_msgs/Header"  # as a generated class names a field's type
STAMP_AT = 4
"""Byte offset of a leading ``std_msgs/Header``'s stamp (and of a Clock's ``clock``): right after the CDR
encapsulation header, a ``builtin_interfaces/Time`` {int32 sec, uint32 nanosec}, 4-aligned."""
_TIME_BY_ENCAPSULATION = {b"\x00\x01": struct.Struct("<iI"), b"\x00\x00": struct.Struct(">iI")}  # plain CDR LE, BE


class StampRule(enum.Enum):
    """Where a topic's log times come from (:func:`stamp_rule`)."""

    CLOCK = "clock"  # rosgraph_msgs/Clock: its own time, which also sets the latest clock
    HEADER = "header"  # first field a std_msgs/Header: header.stamp
    LATEST_CLOCK = "latest clock"  # anything else: the latest clock received


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
