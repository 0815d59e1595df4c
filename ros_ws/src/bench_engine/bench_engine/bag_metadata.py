"""rosbag2's bag metadata (``metadata.yaml`` and the MCAP ``rosbag2`` metadata record) and the QoS profiles it
stores, as rosbag2's ``jazzy`` branch encodes them (``rosbag2_storage/include/rosbag2_storage/yaml.hpp``):
``rosbag2_bagfile_information``, version 9; a topic's offered QoS as a list of profiles with version-9 string
enums; ``custom_data`` (``ros2 bag record --custom-data``) as string keys and values, or ``~`` when empty. The
YAML is written in yaml-cpp's style (:func:`dump_yaml`), so the files read like the ones rosbag2 writes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import yaml

METADATA_VERSION = 9
STORAGE_IDENTIFIER = "mcap"
NS_MAX = 2**63 - 1  # rosbag2's starting time of a bag without messages (nanoseconds::max)

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
    str, lambda d, s: d.represent_scalar("tag:yaml.org,2002:str", s, style='"' if s == "" else None)
)


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


@dataclass
class BagTopic:
    """One topic of a bag: what its metadata lists, and the MCAP channel it is written to (0: not yet)."""

    name: str
    type_name: str
    qos: list[dict[str, Any]]
    type_hash: str
    channel_id: int = 0
    count: int = 0


@dataclass
class LogSpan:
    """The count and the least and greatest log time of the messages written so far."""

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


def string_pairs(items: Mapping[str, str]) -> dict[str, str]:
    """``items`` checked to be rosbag2 custom data: a map of strings to strings."""
    bad = {k: v for k, v in items.items() if not (isinstance(k, str) and isinstance(v, str))}
    if bad:
        raise TypeError(f"custom data maps strings to strings, got {bad!r}")
    return dict(items)


def bag_information(
    topics: Sequence[BagTopic], span: LogSpan, storage_name: str, custom_data: Mapping[str, str], ros_distro: str
) -> dict[str, Any]:
    """The bag metadata (rosbag2 ``BagMetadata``, version 9) of one storage file: the topics that have a channel,
    the messages counted in ``span``. ``starting_time`` and ``duration`` are the least log time and the span to
    the greatest (log times need not be monotonic in the file)."""
    start = {"nanoseconds_since_epoch": span.first_ns}
    duration = {"nanoseconds": span.duration_ns}
    listed = [
        {
            "topic_metadata": {
                "name": t.name,
                "type": t.type_name,
                "serialization_format": "cdr",
                "offered_qos_profiles": t.qos,
                "type_description_hash": t.type_hash,
            },
            "message_count": t.count,
        }
        for t in topics
        if t.channel_id
    ]
    return {
        "version": METADATA_VERSION,
        "storage_identifier": STORAGE_IDENTIFIER,
        "duration": duration,
        "starting_time": start,
        "message_count": span.count,
        "topics_with_message_count": listed,
        "compression_format": "",
        "compression_mode": "",
        "relative_file_paths": [storage_name],
        "files": [{"path": storage_name, "starting_time": start, "duration": duration, "message_count": span.count}],
        "custom_data": dict(custom_data) or None,
        "ros_distro": ros_distro,
    }
