"""All messages of one topic decoded at once into numpy columns, straight from their CDR bytes.

Why: the scorer reads every truth, measurement and estimate of a bag. Decoding them one by one through rclpy's
generated classes builds several Python objects per message (the message, its header, three ``Time``s), most of
a bag's load time. The bench's messages have one byte layout per topic: the same frame, labels and vector sizes at every
step. So a topic's
messages are grouped by layout, and each group's fields are read as strided numpy views of one byte array.

The encoding is the one bench_engine.cdr reads and writes (plain CDR, little endian, field order and types
from rosidl's ``SLOT_TYPES``); types it does not cover (arrays of messages, wide strings) raise
:class:`NoColumnarLayout` (a BagUnsupported and a TypeError): read those with ``BagReader.decoded``.

Hostile bytes: every count and string length is checked against the bytes left before anything is sliced or
allocated, a string must end in its NUL, and its bytes must be UTF-8; a message that fails any of these raises
:class:`~bench_engine.bag_errors.MessageDamaged` naming the message and the field (tests/test_fuzz_readers.py).

A *layout* is what the positions of the fields depend on: the sequence counts and the string bytes. Two
messages of the same length whose length prefixes and strings are byte-equal have the same layout, so one
walk of the first message of a group places the fields of the whole group. tests/test_cdr.py checks
every field against rclpy's own deserialisation.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np

from bench_engine.bag_errors import BagUnsupported, MessageDamaged
from bench_engine.cdr import ENCAPSULATION, HEADER, Field, compiled

BIG_ENDIAN = b"\x00\x00"


class NoColumnarLayout(BagUnsupported, TypeError):
    """A type this decoder does not cover (arrays of messages, wide strings): read it with BagReader.decoded.
    Also a TypeError, what this module raised for it before the readers had their own errors."""


@dataclass
class _Layout:
    """Where one layout puts each field: numeric leaves as (path, byte offset, dtype, count, scalar?),
    strings with their values, and the byte positions the layout depends on."""

    numeric: list[tuple[str, int, np.dtype, int, bool]]
    strings: dict[str, str | tuple[str, ...]]
    structure: np.ndarray  # byte indices (from the start of the payload) that fix the layout


class _Walker:
    """Walks one message's bytes along its compiled type, recording the layout. Every length is checked against
    the bytes left before it is used (:class:`MessageDamaged` otherwise)."""

    def __init__(self, data: bytes):
        if data[:2] != ENCAPSULATION[:2]:
            if data[:2] == BIG_ENDIAN and len(data) >= HEADER:
                raise BagUnsupported("big-endian CDR has no columnar layout here; read it with BagReader.decoded")
            raise MessageDamaged(f"not plain CDR (encapsulation {bytes(data[:2]).hex() or 'missing'})")
        self.data = memoryview(data)[HEADER:]
        self.end = len(self.data)
        self.pos = 0
        self.layout = _Layout([], {}, np.empty(0))
        self._structure: list[range] = [range(-HEADER, 0)]

    def _align(self, n: int) -> None:
        self.pos += -self.pos % n

    def _need(self, n: int, what: str) -> None:
        """Refuse ``n`` more bytes at the current position when the message has fewer left."""
        if self.pos + n > self.end:
            raise MessageDamaged(
                f"message ends inside {what} at byte {self.pos + HEADER} (needs {n} bytes, "
                f"{max(self.end - self.pos, 0)} left): truncated or not of this type"
            )

    def _count(self, path: str) -> int:
        self._align(4)
        self._need(4, f"the length of {path!r}")
        count = int.from_bytes(self.data[self.pos : self.pos + 4], "little")
        self._structure.append(range(self.pos, self.pos + 4))
        self.pos += 4
        return count

    def _string(self, path: str) -> str:
        n = self._count(path)  # bytes, the terminating NUL included (0: empty, as rosbags and Fast CDR read it)
        self._need(n, f"string {path!r}")
        start, self.pos = self.pos, self.pos + n
        if n and self.data[self.pos - 1] != 0:
            raise MessageDamaged(f"string {path!r} does not end in a NUL")
        self._structure.append(range(start, self.pos))
        try:
            return bytes(self.data[start : max(self.pos - 1, start)]).decode("utf-8")
        except UnicodeDecodeError as err:
            raise MessageDamaged(f"string {path!r} is not UTF-8 ({err.reason} at byte {err.start})") from None

    def _numbers(self, path: str, dtype: np.dtype, count: int, scalar: bool = False) -> None:
        if count:  # an empty sequence is its count alone, with no padding after it
            self._align(dtype.itemsize)
        self._need(dtype.itemsize * count, f"field {path!r} ({count} x {dtype})")
        self.layout.numeric.append((path, self.pos, dtype, count, scalar))
        self.pos += dtype.itemsize * count

    def walk(self, fields: tuple[Field, ...], prefix: str = "") -> None:
        for f in fields:
            path = prefix + f.name
            if f.kind == "msg":
                self.walk(f.sub.fields, path + ".")
            elif f.kind == "prim":
                self._numbers(path, f.dtype, 1, scalar=True)
            elif f.kind == "array":
                self._numbers(path, f.dtype, f.size)
            elif f.kind == "seq":
                self._numbers(path, f.dtype, self._count(path))
            elif f.kind == "str":
                self.layout.strings[path] = self._string(path)
            else:  # each string takes at least 5 bytes (its length and NUL): a huge count ends at the first short
                n = f.size if f.kind == "strarray" else self._count(path)
                self.layout.strings[path] = tuple(self._string(f"{path}[{i}]") for i in range(n))

    def finish(self) -> _Layout:
        self.layout.structure = np.concatenate([np.arange(r.start, r.stop) for r in self._structure]) + HEADER
        return self.layout


class Table:
    """The messages of one topic as columns, in the order given.

    ``table[path]`` (``"step"``, ``"header.stamp.sec"``, ``"state"``) is a numpy array with one row per message
    for a number or a fixed-size or same-length vector field; a list (one array per message) for vectors whose
    length varies; a list of str (or of tuples of str) for strings. ``row(i)`` gives message ``i`` as a
    plain object with the message's attribute names (what codecs take)."""

    def __init__(self, columns: dict[str, Any], n: int):
        self.columns = columns
        self.n = n
        self._tree: dict[str, Any] | None = None

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, path: str) -> Any:
        return self.columns[path]

    def seconds(self, prefix: str = "header.stamp") -> np.ndarray:
        """A ``builtin_interfaces/Time`` field as float seconds."""
        return self.columns[prefix + ".sec"] + self.columns[prefix + ".nanosec"] * 1e-9

    def row(self, i: int) -> SimpleNamespace:
        if self._tree is None:
            self._tree = _tree(self.columns)
        return _row(self._tree, i)


def _tree(columns: dict[str, Any]) -> dict[str, Any]:
    """Columns nested by path (``header.stamp.sec`` -> tree["header"]["stamp"]["sec"]); number columns as lists
    of Python numbers, so a row holds what rclpy's messages hold."""
    tree: dict[str, Any] = {}
    for path, column in columns.items():
        *parents, leaf = path.split(".")
        node = tree
        for p in parents:
            node = node.setdefault(p, {})
        node[leaf] = column.tolist() if isinstance(column, np.ndarray) and column.ndim == 1 else column
    return tree


def _row(tree: dict[str, Any], i: int) -> SimpleNamespace:
    return SimpleNamespace(**{k: _row(v, i) if isinstance(v, dict) else v[i] for k, v in tree.items()})


def table(type_name: str, payloads: list[bytes]) -> Table:
    """Decode ``payloads`` (CDR bytes of messages of ``type_name``, ``pkg/msg/Type``) into a :class:`Table`.
    Raises :class:`MessageDamaged` for a message that is not of the type (naming it and the field),
    :class:`NoColumnarLayout` for a type this decoder does not cover, :class:`BagUnsupported` for one that is not
    installed."""
    try:
        fields = compiled(type_name).fields
    except TypeError as err:
        raise NoColumnarLayout(str(err)) from None
    except (LookupError, OSError, ValueError) as err:  # not a type name, or not installed
        raise BagUnsupported(f"message type {type_name!r} cannot be read: {err}") from None
    n = len(payloads)
    parts: dict[str, list[tuple[np.ndarray, Any]]] = {}  # path -> [(row indices, values of a group)]
    lengths = np.fromiter(map(len, payloads), dtype=np.int64, count=n)
    for length in np.unique(lengths):
        index = np.flatnonzero(lengths == length)
        rows = np.frombuffer(b"".join([payloads[i] for i in index]), dtype=np.uint8).reshape(len(index), length)
        todo = np.arange(len(index))
        while todo.size:
            first = int(index[todo[0]])
            try:
                walker = _Walker(payloads[first])
                walker.walk(fields)
            except MessageDamaged as err:
                raise MessageDamaged(f"{type_name} message {first} of {n}: {err}") from None
            layout = walker.finish()
            same = todo[(rows[todo][:, layout.structure] == rows[todo[0], layout.structure]).all(axis=1)]
            for path, values in _group_columns(rows[same], layout).items():
                parts.setdefault(path, []).append((index[same], values))
            todo = np.setdiff1d(todo, same, assume_unique=True)
    return Table({path: _merge(groups, n) for path, groups in parts.items()}, n)


def _group_columns(rows: np.ndarray, layout: _Layout) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for path, offset, dtype, count, scalar in layout.numeric:
        start = HEADER + offset
        block = (
            np.ascontiguousarray(rows[:, start : start + dtype.itemsize * count]).view(dtype)
            if count
            else np.empty((len(rows), 0), dtype)
        )
        out[path] = block[:, 0] if scalar else block
    for path, value in layout.strings.items():
        out[path] = value
    return out


def _merge(groups: list[tuple[np.ndarray, Any]], n: int) -> Any:
    """One column from its groups: an array when every group's rows have one shape, else a list per row."""
    first = groups[0][1]
    if isinstance(first, np.ndarray) and all(
        isinstance(v, np.ndarray) and v.shape[1:] == first.shape[1:] and v.dtype == first.dtype for _, v in groups
    ):
        column = np.empty((n, *first.shape[1:]), dtype=first.dtype)
        for index, values in groups:
            column[index] = values
        return column
    column = [None] * n
    for index, values in groups:
        if isinstance(values, np.ndarray):
            for i, v in zip(index.tolist(), values):
                column[i] = v
        else:
            for i in index.tolist():
                column[i] = values
    return column
