"""The bench's messages on the wire: plain CDR bytes to and from light message objects, without rclpy.

Why: a leo_radar step moves five messages, and rclpy's generated classes cost ~20–30 µs a message each way
(a message, its header and stamps built, every field assignment type- and range-checked, then converted to C);
here a message costs ~4–9 µs each way. The nodes build :func:`lite_class` objects (same attribute names and
defaults, no checks), publish :func:`serialize` bytes (``Publisher.publish(bytes)``) and take raw bytes from
their subscriptions (``raw=True``) to :func:`deserialize`. A leo_radar run in one process used ~7 % less CPU
(4.05 s against 4.33 s, four alternated runs). The bytes are those rclpy sends except for alignment padding,
which rclpy leaves as whatever its reused buffer held and this module zeroes: the digests recorded for four
studies (tests/test_bag_digests.py) still hold, their padding having been zero, and a star_tracker bag now
differs from one recorded before only in padding bytes (same decoded content). tests/test_cdr.py checks
both directions against rclpy on random messages of every type the bench sends.

Encoding: plain CDR, little endian (encapsulation ``00 01 00 00``, as rmw_fastrtps writes it), the OMG XCDR
version 1 rules: every primitive aligned to its size counted from the end of the 4-byte encapsulation
header, padding bytes zero; a string is a uint32 length (the terminating NUL included) then its bytes and the
NUL; a sequence a uint32 count then its elements (no padding after an empty one); a fixed array its bare
elements; a nested message its fields in order. Field order and types come from the generated class's
``SLOT_TYPES`` (rosidl's own description of the type).
"""
from __future__ import annotations

import array
import struct
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache
from operator import attrgetter
from typing import Any

import numpy as np
import rosidl_parser.definition as idl

from bench_engine.msg_schema import message_class

if sys.byteorder != "little":
    raise ImportError("bench_engine.cdr packs numbers in the host's byte order and needs a little-endian host")
ENCAPSULATION = b"\x00\x01\x00\x00"  # plain CDR, little endian, no options
HEADER = len(ENCAPSULATION)
_FORMATS = {  # rosidl primitive -> (numpy dtype, struct format, both little endian)
    "double": ("<f8", "<d"), "float": ("<f4", "<f"), "int64": ("<i8", "<q"), "uint64": ("<u8", "<Q"),
    "int32": ("<i4", "<i"), "uint32": ("<u4", "<I"), "int16": ("<i2", "<h"), "uint16": ("<u2", "<H"),
    "int8": ("i1", "<b"), "uint8": ("u1", "<B"), "octet": ("u1", "<B"), "char": ("u1", "<B"),
    "boolean": ("?", "<?")}
_U32 = struct.Struct("<I")


@dataclass(frozen=True)
class Field:
    """One field of a compiled message type; ``kind``: prim, array, seq, str, strarray, strseq or msg."""

    name: str
    kind: str
    dtype: np.dtype | None = None
    size: int = 0                                   # fixed array length
    sub: "MessageType | None" = None                # nested message
    packer: struct.Struct | None = field(default=None, compare=False)  # a primitive's struct


@dataclass(frozen=True)
class MessageType:
    """A message type's fields in wire order, and its light class."""

    name: str
    fields: tuple[Field, ...]
    lite: type


@lru_cache(maxsize=None)
def compiled(type_name: str) -> MessageType:
    """``pkg/msg/Type`` compiled from its generated class's ``SLOT_TYPES``. Arrays of messages and wide strings
    (no bench message has them) raise a TypeError naming the field."""
    cls = message_class(type_name)
    fields = tuple(_field(name, slot, cls) for name, slot in zip(cls.get_fields_and_field_types(), cls.SLOT_TYPES))
    return MessageType(type_name, fields, _lite(cls, fields))


def _field(name: str, slot: Any, cls: type) -> Field:
    if isinstance(slot, idl.BasicType):
        return Field(name, "prim", _dtype(slot, name, cls), packer=struct.Struct(_FORMATS[slot.typename][1]))
    if isinstance(slot, idl.AbstractString) and not isinstance(slot, idl.AbstractWString):
        return Field(name, "str")
    if isinstance(slot, idl.NamespacedType):
        return Field(name, "msg", sub=compiled("/".join([*slot.namespaces, slot.name])))
    if isinstance(slot, (idl.Array, idl.AbstractSequence)):
        value, fixed = slot.value_type, isinstance(slot, idl.Array)
        if isinstance(value, idl.BasicType):
            return Field(name, "array" if fixed else "seq", _dtype(value, name, cls), slot.size if fixed else 0)
        if isinstance(value, idl.AbstractString) and not isinstance(value, idl.AbstractWString):
            return Field(name, "strarray" if fixed else "strseq", size=slot.size if fixed else 0)
    raise TypeError(f"{cls.__module__}.{cls.__name__}.{name}: arrays of messages and wide strings are not "
                    f"supported here; use rclpy's serialization for this type")


def _dtype(basic: Any, name: str, cls: type) -> np.dtype:
    if basic.typename not in _FORMATS:
        raise TypeError(f"{cls.__name__}.{name}: primitive {basic.typename!r} is not supported here")
    return np.dtype(_FORMATS[basic.typename][0])


def _defaults(cls: type, fields: tuple[Field, ...]) -> list[tuple[str, Any]]:
    """(field, default) from an instance of the generated class: the .msg file's defaults (a Quaternion's
    w = 1) and rclpy's own (0, "", empty). A callable default builds a fresh value for each message."""
    proto = cls()
    out: list[tuple[str, Any]] = []
    for f in fields:
        value = getattr(proto, f.name)
        if f.kind == "msg":
            out.append((f.name, f.sub.lite))
        elif f.kind == "array":
            out.append((f.name, lambda v=np.array(value, dtype=f.dtype): v.copy()))
        elif f.kind in ("seq", "strseq", "strarray"):
            out.append((f.name, lambda v=list(value): list(v)))
        else:
            out.append((f.name, value))
    return out


def _lite(cls: type, fields: tuple[Field, ...]) -> type:
    """A plain class with the message's attributes and defaults, keyword arguments as the generated class
    takes them, and no checks."""
    name, names = cls.__name__, tuple(f.name for f in fields)
    defaults = _defaults(cls, fields)

    def __init__(self, **values: Any) -> None:
        for field_name, default in defaults:
            if field_name in values:
                setattr(self, field_name, values.pop(field_name))
            else:
                setattr(self, field_name, default() if callable(default) else default)
        if values:
            raise TypeError(f"{name} has no field(s) {sorted(values)}")

    def __repr__(self) -> str:
        return f"{name}({', '.join(f'{n}={getattr(self, n)!r}' for n in names)})"

    return type(name, (), {"__slots__": names, "__init__": __init__, "__repr__": __repr__})


def lite_class(type_name: str) -> type:
    """The light class of ``pkg/msg/Type``: what :func:`serialize` takes and :func:`deserialize` returns."""
    return compiled(type_name).lite


# --- serialize --------------------------------------------------------------------------------------------
# Each field compiles once into an "op" that appends the field to the buffer (serialize) or reads it at a
# position (deserialize): the per-message work is then one call per field, with no dispatch on its kind.

Packer = Callable[[bytearray, Any], None]
Unpacker = Callable[[bytearray, int], tuple[Any, int]]
_ZEROS = tuple(bytes(n) for n in range(8))
_ARRAY_CODES = {"<f8": "d", "<f4": "f", "<i8": "q", "<u8": "Q", "<i4": "i", "<u4": "I", "<i2": "h", "<u2": "H",
                "|i1": "b", "|u1": "B"}  # dtype -> array.array typecode (this module requires a little-endian host)
_STRINGS_CACHE = 256                      # distinct string lists (labels, names) kept packed


def serialize(type_name: str, msg: Any) -> bytes:
    """CDR bytes of ``msg`` (a light or generated message object of ``type_name``), as a publisher sends it."""
    buf = bytearray(ENCAPSULATION)
    _packer(type_name)(buf, msg)
    return bytes(buf)


@lru_cache(maxsize=None)
def _packer(type_name: str) -> Packer:
    mtype = compiled(type_name)
    names = tuple(f.name for f in mtype.fields)
    ops = tuple(_op(f, PACK) for f in mtype.fields)
    getter = attrgetter(*names) if len(names) > 1 else (lambda msg, name=names[0]: (getattr(msg, name),))

    def pack(buf: bytearray, msg: Any) -> None:
        for op, value in zip(ops, getter(msg)):
            op(buf, value)
    return pack


def _pack_str(buf: bytearray, text: str) -> None:
    data = text.encode("utf-8")
    buf += _ZEROS[-(len(buf) - HEADER) % 4]
    buf += _U32.pack(len(data) + 1)
    buf += data
    buf += b"\x00"


def _prim_packer(size: int, pack: Callable[[Any], bytes]) -> Packer:
    def op(buf: bytearray, value: Any) -> None:
        buf += _ZEROS[-(len(buf) - HEADER) % size]
        buf += pack(value)
    return op


def _numbers_packer(f: Field) -> Packer:
    dtype, size, fixed = f.dtype, f.dtype.itemsize, f.kind == "array"
    code = _ARRAY_CODES.get(dtype.str)

    def op(buf: bytearray, value: Any) -> None:
        if code is not None and isinstance(value, (list, tuple)):
            data = array.array(code, value).tobytes()
        else:
            data = np.asarray(value, dtype=dtype).tobytes()
        n = len(data) // size
        if fixed and n != f.size:
            raise ValueError(f"{f.name}: {n} values for a {f.size}-array")
        if not fixed:
            buf += _ZEROS[-(len(buf) - HEADER) % 4]
            buf += _U32.pack(n)
        if n:
            buf += _ZEROS[-(len(buf) - HEADER) % size]
            buf += data
    return op


def _strings_packer(f: Field) -> Packer:
    """A sequence (or fixed array) of strings; the same list at the same alignment packs to the same bytes,
    kept for the next message (a topic's labels and names rarely change)."""
    cache: dict[tuple, bytes] = {}

    def op(buf: bytearray, value: Any) -> None:
        if f.kind == "strarray" and len(value) != f.size:
            raise ValueError(f"{f.name}: {len(value)} strings for a {f.size}-array")
        key = ((len(buf) - HEADER) % 4, *value)
        packed = cache.get(key)
        if packed is None:
            part = bytearray(ENCAPSULATION + bytes(key[0]))  # the same alignment as in buf
            if f.kind == "strseq":
                part += _ZEROS[-key[0] % 4]
                part += _U32.pack(len(value))
            for text in value:
                _pack_str(part, text)
            if len(cache) >= _STRINGS_CACHE:
                cache.clear()
            packed = cache[key] = bytes(part[HEADER + key[0]:])
        buf += packed
    return op


# --- deserialize ------------------------------------------------------------------------------------------

def deserialize(type_name: str, data: bytes) -> Any:
    """A light message of ``type_name`` from its CDR bytes (little-endian plain CDR, as rclpy writes it).
    Number sequences and arrays come as writable numpy arrays (rclpy gives array.array / numpy)."""
    if data[:2] != ENCAPSULATION[:2]:
        raise ValueError(f"{type_name}: not little-endian plain CDR (encapsulation {bytes(data[:2]).hex()})")
    buf = bytearray(data)
    try:
        msg, end = _unpacker(type_name)(buf, HEADER)
    except struct.error as err:
        raise ValueError(f"{type_name}: message ends early (truncated or another type): {err}") from None
    if end > len(buf):
        raise ValueError(f"{type_name}: message ends {end - len(buf)} bytes early (truncated or another type)")
    return msg


@lru_cache(maxsize=None)
def _unpacker(type_name: str) -> Unpacker:
    mtype = compiled(type_name)
    lite = mtype.lite
    ops = tuple((f.name, _op(f, UNPACK)) for f in mtype.fields)

    def unpack(buf: bytearray, pos: int) -> tuple[Any, int]:
        msg = lite.__new__(lite)
        for name, op in ops:
            value, pos = op(buf, pos)
            setattr(msg, name, value)
        return msg, pos
    return unpack


def _count(buf: bytearray, pos: int) -> tuple[int, int]:
    pos += -(pos - HEADER) % 4
    return _U32.unpack_from(buf, pos)[0], pos + 4


def _prim_unpacker(size: int, unpack_from: Callable) -> Unpacker:
    def op(buf: bytearray, pos: int) -> tuple[Any, int]:
        pos += -(pos - HEADER) % size
        return unpack_from(buf, pos)[0], pos + size
    return op


def _unpack_str(buf: bytearray, pos: int) -> tuple[str, int]:
    n, pos = _count(buf, pos)
    return buf[pos:pos + max(n - 1, 0)].decode("utf-8"), pos + n


def _numbers_unpacker(f: Field) -> Unpacker:
    dtype, size, fixed = f.dtype, f.dtype.itemsize, f.kind == "array"

    def op(buf: bytearray, pos: int) -> tuple[Any, int]:
        if fixed:
            n = f.size
        else:
            n, pos = _count(buf, pos)
        if not n:
            return np.empty(0, dtype), pos
        pos += -(pos - HEADER) % size
        return np.frombuffer(buf, dtype, n, pos), pos + n * size
    return op


def _strings_unpacker(f: Field) -> Unpacker:
    def op(buf: bytearray, pos: int) -> tuple[list[str], int]:
        if f.kind == "strarray":
            n = f.size
        else:
            n, pos = _count(buf, pos)
        out = []
        for _ in range(n):
            text, pos = _unpack_str(buf, pos)
            out.append(text)
        return out, pos
    return op


# --- one packer and one unpacker per kind of field --------------------------------------------------------

PACK, UNPACK = 0, 1
_OPS: dict[str, tuple[Callable[[Field], Packer], Callable[[Field], Unpacker]]] = {
    "prim": (lambda f: _prim_packer(f.dtype.itemsize, f.packer.pack),
             lambda f: _prim_unpacker(f.dtype.itemsize, f.packer.unpack_from)),
    "msg": (lambda f: _packer(f.sub.name), lambda f: _unpacker(f.sub.name)),
    "str": (lambda f: _pack_str, lambda f: _unpack_str),
    "array": (_numbers_packer, _numbers_unpacker),
    "seq": (_numbers_packer, _numbers_unpacker),
    "strarray": (_strings_packer, _strings_unpacker),
    "strseq": (_strings_packer, _strings_unpacker),
}


def _op(f: Field, direction: int) -> Callable:
    """The op that appends field ``f`` to a buffer (PACK) or reads it at a position (UNPACK)."""
    return _OPS[f.kind][direction](f)
