"""ROS 2 message definitions as rosbag2 embeds them in MCAP schemas, plus type hashes and generated classes.

rosbag2 (Jazzy, ``rosbag2_cpp/src/rosbag2_cpp/message_definitions/local_message_definition_source.cpp``,
``LocalMessageDefinitionSource::get_full_text``) stores for a topic type the raw text of its ``.msg`` file,
then every message type it depends on exactly once: the dependencies of each definition are visited in
sorted (byte) order, depth-first, and each one is appended as ``"\\n" + "=" * 80 + "\\nMSG: <dep>\\n" +
<dep's .msg text>``. ``<dep>`` is spelled as in the field declaration (``std_msgs/Header``), with the
enclosing package prepended to bare names (``Pose`` -> ``geometry_msgs/Pose``). Field types are found with
rosbag2's own pattern, so the text here is byte-identical to what ``ros2 bag record`` writes.

Definitions are looked up in ``<prefix>/share/<pkg>/msg/`` for each prefix of ``AMENT_PREFIX_PATH`` and then
the interpreter's prefix (``sys.prefix``: the venv the PyPI wheels are installed in).
"""

from __future__ import annotations

import importlib
import json
import os
import re
import sys
from functools import cache
from pathlib import Path

SEPARATOR = "=" * 80

_TYPE_NAME = re.compile(r"^([a-zA-Z0-9_]+)/(?:msg/)?([a-zA-Z0-9_]+)$")
# rosbag2's MSG_FIELD_TYPE_REGEX: the first word of a line, optionally followed by an array suffix.
_FIELD_TYPE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
PRIMITIVE_TYPES = frozenset(
    {
        "bool",
        "byte",
        "char",
        "float32",
        "float64",
        "int8",
        "uint8",
        "int16",
        "uint16",
        "int32",
        "uint32",
        "int64",
        "uint64",
        "string",
    }
)


def split_type_name(type_name: str) -> tuple[str, str]:
    """``"pkg/msg/Type"`` or ``"pkg/Type"`` -> ``("pkg", "Type")``."""
    match = _TYPE_NAME.match(type_name)
    if match is None:
        raise ValueError(f"not a message type name (pkg/msg/Type): {type_name!r}")
    return match.group(1), match.group(2)


def share_prefixes() -> list[Path]:
    """Install prefixes searched for ``share/<pkg>``: ``AMENT_PREFIX_PATH`` entries, then ``sys.prefix``."""
    entries = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    prefixes: list[Path] = []
    for entry in [*entries, sys.prefix]:
        path = Path(entry)
        if path not in prefixes:
            prefixes.append(path)
    return prefixes


def interface_file(type_name: str, suffix: str) -> Path:
    """The installed ``share/<pkg>/msg/<Type><suffix>`` file of a message type."""
    package, name = split_type_name(type_name)
    for prefix in share_prefixes():
        path = prefix / "share" / package / "msg" / f"{name}{suffix}"
        if path.is_file():
            return path
    searched = ", ".join(str(p) for p in share_prefixes())
    raise FileNotFoundError(f"no {package}/msg/{name}{suffix} under share/ of {searched}")


@cache
def msg_text(type_name: str) -> str:
    """The raw text of a type's installed ``.msg`` file (comments and line endings kept)."""
    return interface_file(type_name, ".msg").read_bytes().decode("utf-8")


def dependencies(text: str, package: str) -> list[str]:
    """Non-primitive field types of a ``.msg`` text, sorted, as rosbag2's ``parse_msg_dependencies`` finds them."""
    found = set()
    for match in _FIELD_TYPE.finditer(text):
        field_type = match.group(1)
        if field_type in PRIMITIVE_TYPES:
            continue
        found.add(field_type if "/" in field_type else f"{package}/{field_type}")
    return sorted(found)


def schema_text(type_name: str) -> str:
    """The full message definition rosbag2 stores as the MCAP schema (encoding ``ros2msg``) of ``type_name``."""
    seen: set[str] = set()

    def expand(name: str) -> str:
        text = msg_text(name)
        parts = [text]
        for dep in dependencies(text, split_type_name(name)[0]):
            if dep not in seen:
                seen.add(dep)
                parts.append(f"\n{SEPARATOR}\nMSG: {dep}\n")
                parts.append(expand(dep))
        return "".join(parts)

    return expand(type_name)


def canonical_type_name(type_name: str) -> str:
    """``"pkg/Type"`` or ``"pkg/msg/Type"`` -> ``"pkg/msg/Type"``."""
    package, name = split_type_name(type_name)
    return f"{package}/msg/{name}"


@cache
def type_hash(type_name: str) -> str:
    """The type's ``RIHS01_...`` hash, read from the type description ``.json`` rosidl installs next to the .msg."""
    description = json.loads(interface_file(type_name, ".json").read_text(encoding="utf-8"))
    wanted = canonical_type_name(type_name)
    for entry in description["type_hashes"]:
        if entry["type_name"] == wanted:
            return entry["hash_string"]
    raise KeyError(f"{wanted} has no hash in its type description")


def message_class(type_name: str) -> type:
    """The generated Python class of a message type (``import pkg.msg; pkg.msg.Type``)."""
    package, name = split_type_name(type_name)
    return getattr(importlib.import_module(f"{package}.msg"), name)
