"""The bench's messages on the wire: CDR bytes to and from light message objects, through rosbags' typestore.

Why: rclpy's generated classes are costly per message each way (a message, its header and stamps built, every
field assignment type- and range-checked, then converted to C; scripts/bench_cdr.py measures the bench's path).
The nodes build :func:`lite_class` objects instead (rclpy's attribute names and defaults, no checks), publish
:func:`serialize` bytes (``Publisher.publish(bytes)``) and take raw bytes from their subscriptions
(``raw=True``) to :func:`deserialize`.

The encoding itself is rosbags' (https://gitlab.com/ternaris/rosbags, pinned in requirements.txt): its
typestore holds ROS 2 Jazzy's message definitions (``Stores.ROS2_JAZZY``) and compiles a serialiser and a
deserialiser per type; the bench registers its own types (bench_msgs, and any other type not in the store)
from the ``.msg`` files rosidl installed (bench_engine.msg_schema). This module only adds the light classes
(installed as the typestore's classes, so rosbags' deserialiser builds them directly) and, before a message
is serialised, turns the number sequences codecs set as lists into the numpy arrays rosbags writes. Bytes:
plain CDR, little endian, alignment padding zeroed, i.e. what rclpy sends except for the padding (rclpy leaves
its reused buffer's bytes there), and a message is padded with zeros to a multiple of 4 bytes: DDS pads a
payload it sends to another process so, and without it a message of another length (one ending in a string or
a bool, as a DiagnosticArray or a Marker) would reach the recorder with 1–3 more bytes from a node in another
process than from one in the same process (``--single-process``). Readers ignore the bytes after a message.
A seeded run's recorded bytes did not change when this module moved from a hand-written encoder to rosbags
(the bench's own messages are multiples of 4 bytes long). tests/test_cdr.py checks both
directions against rclpy on random messages of every type the bench sends, its standard views
(nav_msgs/Odometry, geometry_msgs/PoseWithCovarianceStamped, diagnostic_msgs/DiagnosticArray with its arrays
of messages, which the hand-written encoder did not cover, visualization_msgs/Marker) included.

Conventions of the light messages (where they differ from rclpy's classes):

* number sequences and arrays may be set as lists, tuples, array.array or numpy arrays of any shape (they are
  sent flattened); :func:`serialize` replaces them on the message by the contiguous 1-D numpy arrays of the
  field's type it sent; :func:`deserialize` returns writable numpy arrays (rclpy: array.array / numpy);
* a ``byte`` field is an int in [-128, 127] (rosbags' convention; rclpy holds a 1-byte ``bytes``): 0 by
  default, as rclpy's ``b"\\x00"``; a message's constants are class attributes, as in rclpy
  (``DiagnosticStatus.WARN == 1``);
* arrays of messages are lists of light messages (a fixed-size one of exactly its size).

``scripts/bench_cdr.py`` measures the cost of one StateEstimate built by its codec, then serialised /
deserialised.

:func:`compiled` describes a type's fields for the columnar bag decoder (bench_engine.columns), which reads
whole topics as numpy columns without building messages.
"""

from __future__ import annotations

import struct
import sys
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from functools import cache
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from bench_engine.msg_schema import (
    canonical_type_name,
    dependencies,
    interface_file,
    message_class,
    msg_text,
    split_type_name,
)

ENCAPSULATION = b"\x00\x01\x00\x00"  # plain CDR, little endian, no options (what rmw_fastrtps writes)
HEADER = len(ENCAPSULATION)
_DTYPES = {  # rosbags' primitive names -> numpy dtype of the wire values (little endian)
    "float64": "<f8",
    "float32": "<f4",
    "int64": "<i8",
    "uint64": "<u8",
    "int32": "<i4",
    "uint32": "<u4",
    "int16": "<i2",
    "uint16": "<u2",
    "int8": "i1",
    "uint8": "u1",
    "byte": "u1",
    "char": "u1",
    "octet": "u1",
    "bool": "?",
}
_LITTLE = sys.byteorder == "little"


# --- the typestore ----------------------------------------------------------------------------------------


@cache
def typestore() -> Typestore:
    """This process's typestore: ROS 2 Jazzy's types, then the bench's as they are first used. Its classes are
    the light classes (:func:`lite_class`), so it is the bench's own: to read bags with rosbags' classes, use
    ``rosbags.typesys.get_typestore`` (it builds a new store each call)."""
    return get_typestore(Stores.ROS2_JAZZY)


def _registered(type_name: str) -> str:
    """``type_name`` as the typestore spells it (``pkg/msg/Type``), registered from its installed ``.msg`` file
    (and its dependencies) if the store does not hold it yet."""
    name = canonical_type_name(type_name)
    store = typestore()
    if name not in store.fielddefs:
        text = msg_text(name)
        for dep in dependencies(text, split_type_name(name)[0]):
            _registered(dep)
        store.register(get_types_from_msg(text, name))
    return name


def _fields(name: str) -> list[tuple[str, tuple]]:
    return list(typestore().fielddefs[name][1])


def _constants(name: str) -> list[tuple[str, str, Any]]:
    return list(typestore().fielddefs[name][0])


def _is_number(desc: tuple) -> bool:
    """A BASE field descriptor of a number (not a string)."""
    return desc[0] == Nodetype.BASE and desc[1][0] not in ("string", "wstring")


def _dtype(desc: tuple) -> np.dtype:
    return np.dtype(_DTYPES[desc[1][0]])


# --- light classes ----------------------------------------------------------------------------------------


class _Missing:
    def __repr__(self) -> str:
        return "<default>"


_MISSING = _Missing()


@cache
def _lite(name: str) -> type:
    """The light class of canonical type ``name``, installed as the typestore's class of the type (and of every
    type it nests) before rosbags compiles any of them."""
    store = typestore()
    fields = _fields(name)
    proto = message_class(name)()
    ns: dict[str, Any] = {"_M": _MISSING, "_byte": _as_byte}
    params, body = [], []
    for i, (attr, desc) in enumerate(fields):
        kind, sub = desc[0], desc[1]
        if kind == Nodetype.NAME:
            ns[f"_f{i}"] = _lite(_registered(sub))
        elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE) and sub[0][0] == Nodetype.NAME:
            cls = _lite(_registered(sub[0][1]))
            ns[f"_f{i}"] = (lambda c=cls, n=sub[1]: [c() for _ in range(n)]) if kind == Nodetype.ARRAY else list
        elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE) and _is_number(sub[0]):
            default = np.array(getattr(proto, attr), dtype=_dtype(sub[0])).reshape(-1)
            ns[f"_f{i}"] = default.copy
        elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):  # strings
            ns[f"_f{i}"] = lambda v=list(getattr(proto, attr)): list(v)  # noqa: B008 - the default, read once
        else:
            value = getattr(proto, attr)
            if desc[1][0] in ("byte", "char"):
                ns[f"_d{i}"] = _as_byte(value) if desc[1][0] == "byte" else _as_char(value)
                params.append(f"{attr}=_d{i}")
                body.append(
                    f"    self.{attr} = {attr} if {attr}.__class__ is int else _byte({attr})"
                    if desc[1][0] == "byte"
                    else f"    self.{attr} = {attr}"
                )
                continue
            ns[f"_d{i}"] = value
            params.append(f"{attr}=_d{i}")
            body.append(f"    self.{attr} = {attr}")
            continue
        params.append(f"{attr}=_M")
        body.append(f"    self.{attr} = _f{i}() if {attr} is _M else {attr}")
    short = name.rsplit("/", 1)[-1]
    source = (
        f"def __init__(self, {', '.join(params)}{', ' if params else ''}**_unknown):\n" + "\n".join(body) + "\n"
        f"    if _unknown:\n"
        f"        raise TypeError(f'{short} has no field(s) {{sorted(_unknown)}}')\n"
    )
    exec(source, ns)  # noqa: S102 - the code is built above from the type's field names only
    names = tuple(attr for attr, _ in fields)

    def __repr__(self) -> str:
        return f"{short}({', '.join(f'{n}={getattr(self, n)!r}' for n in names)})"

    attrs: dict[str, Any] = {
        "__slots__": names,
        "__init__": ns["__init__"],
        "__repr__": __repr__,
        "__msgtype__": name,
        "__doc__": f"Light message of {name} (bench_engine.cdr).",
    }
    for const, _ctype, value in _constants(name):
        attrs[const] = value
    cls = type(short, (), attrs)
    store.types[name] = cls
    return cls


def _as_byte(value: Any) -> int:
    """A ``byte`` field's value as rosbags packs it: a signed int (rclpy: ``b"\\xff"`` -> -1)."""
    if isinstance(value, (bytes, bytearray)):
        return int.from_bytes(bytes(value), "little", signed=True)
    return int(value)


def _as_char(value: Any) -> int:
    return ord(value) if isinstance(value, str) else int(value)


@cache
def lite_class(type_name: str) -> type:
    """The light class of ``pkg/msg/Type`` (or ``pkg/Type``): what :func:`serialize` takes and
    :func:`deserialize` returns. Keyword (or positional, in field order) arguments, rclpy's defaults. Cached by
    the name as given: the views look their classes up for every message they build."""
    return _lite(_registered(type_name))


# --- serialize --------------------------------------------------------------------------------------------


def serialize(type_name: str, msg: Any) -> bytes:
    """CDR bytes of ``msg`` (a light message of ``type_name``, or any object with its fields: an rclpy
    message, a rosbags one), as a publisher sends them."""
    try:
        return _SERIALIZERS[type_name](msg)
    except KeyError:
        if type_name in _SERIALIZERS:
            raise
        _SERIALIZERS[type_name] = _serializer(type_name)
        return _SERIALIZERS[type_name](msg)


_SERIALIZERS: dict[str, Callable[[Any], bytes]] = {}


def _serializer(type_name: str) -> Callable[[Any], bytes]:
    name = _registered(type_name)
    lite, store = _lite(name), typestore()
    prepare, convert = _preparer(name), _converter(name)
    msgdef = store.get_msgdef(name)
    getsize, write = msgdef.getsize_cdr, msgdef.serialize_cdr_le if _LITTLE else msgdef.serialize_cdr_be

    def ser(msg: Any) -> bytes:
        if msg.__class__ is not lite:
            msg = convert(msg)
        prepare(msg)
        try:
            size = getsize(0, msg, store)
            raw = bytearray(HEADER + size + (-size & 3))  # zero padding to a multiple of 4 bytes (module doc)
            raw[1] = _LITTLE
            write(memoryview(raw)[HEADER:], 0, msg, store)
        except SerdeError as err:  # e.g. a fixed-size array of messages of another length
            raise ValueError(f"{type_name}: {err}") from None
        return bytes(raw)

    return ser


def _coerce(attr: str, dtype: np.dtype, size: int | None) -> Callable[[Any], np.ndarray]:
    """A number field's value as the contiguous 1-D array of ``dtype`` rosbags writes (``size``: a fixed
    array's length, checked)."""

    def coerce(value: Any) -> np.ndarray:
        out = np.ascontiguousarray(value, dtype=dtype).reshape(-1)
        if size is not None and len(out) != size:
            raise ValueError(f"{attr}: {len(out)} values for a {size}-array")
        return out

    return coerce


@cache
def _needs_preparing(name: str) -> bool:
    """Whether a type, or a type it nests, has number sequences or byte fields (what rosbags' serialiser cannot
    take as codecs and rclpy's messages give them). Other nested messages may be any object with their
    fields: rosbags reads them attribute by attribute."""
    for _, desc in _fields(name):
        kind, sub = desc[0], desc[1]
        if kind == Nodetype.BASE:
            if sub[0] in ("byte", "char"):
                return True
        elif kind == Nodetype.NAME:
            if _needs_preparing(_registered(sub)):
                return True
        elif sub[0][0] == Nodetype.NAME:
            if _needs_preparing(_registered(sub[0][1])):
                return True
        elif _is_number(sub[0]):
            return True
    return False


@cache
def _preparer(name: str) -> Callable[[Any], None]:
    """A function that makes a light message of ``name`` ready for rosbags' serialiser, in place: number
    sequences as contiguous 1-D arrays of their type, byte fields as ints, nested messages that hold such fields
    as light messages. Only those fields are visited (a type without any gets a no-op)."""
    if not _needs_preparing(name):
        return _noop
    ns: dict[str, Any] = {"_nd": np.ndarray, "_array": np.array, "_byte": _as_byte, "_char": _as_char}
    lines: list[str] = []
    for i, (attr, desc) in enumerate(_fields(name)):
        kind, sub = desc[0], desc[1]
        if kind == Nodetype.NAME:
            sub_name = _registered(sub)
            if not _needs_preparing(sub_name):
                continue
            ns[f"_L{i}"], ns[f"_c{i}"], ns[f"_p{i}"] = _lite(sub_name), _converter(sub_name), _preparer(sub_name)
            lines += [
                f"  v = msg.{attr}",
                f"  if v.__class__ is not _L{i}:",
                f"    msg.{attr} = v = _c{i}(v)",
                f"  _p{i}(v)",
            ]
        elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE) and sub[0][0] == Nodetype.NAME:
            sub_name = _registered(sub[0][1])
            if not _needs_preparing(sub_name):
                continue
            ns[f"_L{i}"], ns[f"_c{i}"], ns[f"_p{i}"] = _lite(sub_name), _converter(sub_name), _preparer(sub_name)
            lines += [
                f"  v = msg.{attr}",
                "  if v.__class__ is not list:",
                f"    msg.{attr} = v = list(v)",
                "  for j, m in enumerate(v):",
                f"    if m.__class__ is not _L{i}:",
                f"      v[j] = m = _c{i}(m)",
                f"    _p{i}(m)",
            ]
        elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE) and _is_number(sub[0]):
            dtype = _dtype(sub[0])
            ns[f"_t{i}"] = dtype
            ns[f"_k{i}"] = _coerce(attr, dtype, sub[1] if kind == Nodetype.ARRAY else None)
            fixed = kind == Nodetype.ARRAY
            lines += [
                f"  v = msg.{attr}",  # a list (what codecs give) of numbers: straight to an array
                f"  if v.__class__ is list{f' and len(v) == {sub[1]}' if fixed else ''}:",
                f"    msg.{attr} = _array(v, _t{i})",
                f"  elif v.__class__ is not _nd or v.dtype is not _t{i} or v.ndim != 1"
                f" or not v.flags.c_contiguous{f' or len(v) != {sub[1]}' if fixed else ''}:",
                f"    msg.{attr} = _k{i}(v)",
            ]
        elif kind == Nodetype.BASE and sub[0] in ("byte", "char"):
            lines += [
                f"  v = msg.{attr}",
                "  if v.__class__ is not int:",
                f"    msg.{attr} = {'_byte' if sub[0] == 'byte' else '_char'}(v)",
            ]
    exec("def prepare(msg):\n" + "\n".join(lines) + "\n", ns)  # noqa: S102 - built from field names only
    return ns["prepare"]


def _noop(msg: Any) -> None:
    return None


@cache
def _converter(name: str) -> Callable[[Any], Any]:
    """Any object with the fields of ``name`` (rclpy's message, rosbags', a table row) -> a light message."""
    lite = _lite(name)
    steps: list[tuple[str, Callable[[Any], Any]]] = []
    for attr, desc in _fields(name):
        kind, sub = desc[0], desc[1]
        if kind == Nodetype.NAME:
            steps.append((attr, _converter(_registered(sub))))
        elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE) and sub[0][0] == Nodetype.NAME:
            conv = _converter(_registered(sub[0][1]))
            steps.append((attr, lambda v, c=conv: [c(m) for m in v]))
        elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE) and _is_number(sub[0]):
            steps.append((attr, _coerce(attr, _dtype(sub[0]), sub[1] if kind == Nodetype.ARRAY else None)))
        elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            steps.append((attr, list))
        elif sub[0] == "byte":
            steps.append((attr, _as_byte))
        elif sub[0] == "char":
            steps.append((attr, _as_char))
        else:
            steps.append((attr, lambda v: v))

    def convert(obj: Any) -> Any:
        if obj.__class__ is lite:
            return obj
        return lite(**{attr: conv(getattr(obj, attr)) for attr, conv in steps})

    return convert


# --- deserialize ------------------------------------------------------------------------------------------


def deserialize(type_name: str, data: bytes) -> Any:
    """A light message of ``type_name`` from its CDR bytes (plain CDR, either byte order; bytes after the message
    are ignored, as rclpy does). Number sequences and arrays come as writable numpy arrays."""
    try:
        read = _DESERIALIZERS[type_name]
    except KeyError:
        read = _DESERIALIZERS[type_name] = _deserializer(type_name)
    return read(data)


_DESERIALIZERS: dict[str, Callable[[bytes], Any]] = {}


def _deserializer(type_name: str) -> Callable[[bytes], Any]:
    name = _registered(type_name)
    _lite(name)
    store = typestore()
    msgdef = store.get_msgdef(name)
    readers = {b"\x00\x01": msgdef.deserialize_cdr_le, b"\x00\x00": msgdef.deserialize_cdr_be}
    cls = msgdef.cls

    def read(data: bytes) -> Any:
        # rosbags' deserialiser for the byte order, called directly: Typestore.deserialize_cdr refuses more than
        # 3 bytes after the message, and rclpy's serialize_message may leave more (rmw's size estimate).
        reader = readers.get(bytes(data[:2]))
        if reader is None:
            raise ValueError(f"{type_name}: not plain CDR (encapsulation {bytes(data[:2]).hex()})")
        try:
            return reader(memoryview(bytearray(data))[HEADER:], 0, cls, store)[0]
        except (SerdeError, struct.error, ValueError, UnicodeDecodeError, IndexError) as err:
            raise ValueError(f"{type_name}: message ends early or is of another type: {err}") from None

    return read


# --- the layout the columnar decoder reads ----------------------------------------------------------------


@dataclass(frozen=True)
class Field:
    """One field of a type as bench_engine.columns walks it; ``kind``: prim, array, seq, str, strarray, strseq
    or msg."""

    name: str
    kind: str
    dtype: np.dtype | None = None
    size: int = 0  # fixed array length
    sub: MessageType | None = None  # nested message


@dataclass(frozen=True)
class MessageType:
    """A type's fields in wire order, and its light class."""

    name: str
    fields: tuple[Field, ...]
    lite: type


@cache
def compiled(type_name: str) -> MessageType:
    """``pkg/msg/Type``'s fields, from the typestore, for the columnar decoder. Arrays of messages and wide
    strings (no topic the scorer reads has them) raise a TypeError naming the field: read such a type with
    :func:`deserialize` (``BagReader.decoded``)."""
    name = _registered(type_name)
    return MessageType(name, tuple(_layout_field(name, attr, desc) for attr, desc in _fields(name)), _lite(name))


def _layout_field(name: str, attr: str, desc: tuple) -> Field:
    kind, sub = desc[0], desc[1]
    if kind == Nodetype.BASE and sub[0] == "string":
        return Field(attr, "str")
    if kind == Nodetype.BASE and sub[0] in _DTYPES:
        return Field(attr, "prim", _dtype(desc))
    if kind == Nodetype.NAME:
        return Field(attr, "msg", sub=compiled(sub))
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        fixed, size = kind == Nodetype.ARRAY, sub[1] if kind == Nodetype.ARRAY else 0
        if _is_number(sub[0]) and sub[0][1][0] in _DTYPES:
            return Field(attr, "array" if fixed else "seq", _dtype(sub[0]), size)
        if sub[0][0] == Nodetype.BASE and sub[0][1][0] == "string":
            return Field(attr, "strarray" if fixed else "strseq", size=size)
    raise TypeError(
        f"{name}.{attr}: arrays of messages and wide strings have no columnar layout here; "
        f"decode this type message by message (bench_engine.cdr.deserialize)"
    )


def warm(type_names: Iterable[str]) -> None:
    """Compile the light class, serialiser and deserialiser of each type now (rosbags compiles code per type and
    nested type). The launcher and the Monte Carlo fork server do it before they fork the nodes
    and runs (bench_engine.views at import), so these inherit the compiled code instead of compiling it each."""
    for name in type_names:
        _SERIALIZERS.setdefault(name, _serializer(name))
        _DESERIALIZERS.setdefault(name, _deserializer(name))


def bench_types() -> list[str]:
    """The message types the bench's nodes send as CDR: every installed bench_msgs type and /clock's."""
    share = interface_file("bench_msgs/msg/StepAck", ".msg").parent
    return [f"bench_msgs/msg/{path.stem}" for path in sorted(share.glob("*.msg"))] + ["rosgraph_msgs/msg/Clock"]
