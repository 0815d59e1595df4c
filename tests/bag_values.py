"""A bag's messages as decoded values, compared with stated tolerances instead of bytes (tests/test_bag_regression.py).

numpy picks its SIMD kernels and OpenBLAS its matrix kernels by CPU (``np.show_runtime()``; the environment
variables ``NPY_DISABLE_CPU_FEATURES`` and ``OPENBLAS_CORETYPE`` change the choice), so the same seeded run gives
floating-point results that differ in their last bits from one machine to another. What a run decided does not:
message counts, steps, stamps, frames, labels, NaN patterns, star identifications. So a bag is read back with
``rosbags`` (the independent reader) into *columns*, one per topic and field path (``/ukf/estimate`` ``state``,
``/ekf/diagnostics`` ``status[0].values[1].value``), and two bags are compared column by column:

- every non-float value (integers, strings, booleans, integer arrays, array lengths) exactly, and where a float
  is NaN or infinite;
- every float within ``rtol`` of its column's *scale*: the largest magnitude that component takes over the
  reference run (a position's orbit radius, a variance's initial value), or for the off-diagonal entry (i, j) of
  a ``covariance`` field the Cauchy-Schwarz bound S_i S_j of its column, S_i the largest standard deviation of
  component i over the run. A relative tolerance per value would fail wherever a value crosses zero (a position
  component, a cross-covariance) or is itself rounding noise (a particle filter's collapsed cloud); the column's
  scale is what its last bits are relative to.

A diagnostics ``KeyValue`` carries a number as text (``repr(float)``): it is parsed and compared as a float.

References are stored compactly (``save``/``load``: the columns as arrays of one zstd-compressed ``.npz``; floats
rounded to float32, whose relative precision 2**-24 = 6e-8 is well below the tolerance used, so the rounding never
decides a comparison: test_bag_regression.py's regeneration checks it).
"""

from __future__ import annotations

import io
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import zstandard
from rosbags.highlevel import AnyReader

KEY_VALUE = "diagnostic_msgs/msg/KeyValue"
STORED_FLOAT = np.float32
"""Reference floats are stored at this precision (relative 2**-24 = 6e-8)."""
STORED_RTOL = 2.0**-24


@dataclass
class Column:
    """One field path of one topic over its messages: ``values`` one entry per message that has the path (an
    array for array fields); ``floats`` whether compared with a tolerance."""

    floats: bool
    values: list = field(default_factory=list)
    present: list[int] = field(default_factory=list)
    """Indices of the messages that have this path (a nested list's entries may come and go)."""


@dataclass
class Topic:
    msgtype: str
    count: int = 0
    columns: dict[str, Column] = field(default_factory=dict)


def _number_text(text: str) -> float | None:
    try:
        return float(text)
    except ValueError:
        return None


def _flatten(msg, prefix: str, out: dict) -> None:
    """path -> value of one decoded message (nested messages by dotted path, lists of them indexed)."""
    for name in msg.__dataclass_fields__:
        value = getattr(msg, name)
        path = f"{prefix}.{name}" if prefix else name
        if hasattr(value, "__msgtype__"):
            _flatten(value, path, out)
        elif isinstance(value, list):
            out[f"{path}#len"] = len(value)
            for i, item in enumerate(value):
                if hasattr(item, "__msgtype__"):
                    _flatten(item, f"{path}[{i}]", out)
                else:
                    out[f"{path}[{i}]"] = item
        elif name == "value" and msg.__msgtype__ == KEY_VALUE and _number_text(value) is not None:
            out[path] = _number_text(value)
        else:
            out[path] = value


def _is_float(value) -> bool:
    return isinstance(value, float) or (isinstance(value, np.ndarray) and value.dtype.kind == "f")


def read(bag: Path) -> dict[str, Topic]:
    """Every topic's messages as columns (rosbags reads the bag, in the recorder's write order), with each
    message's log time (an integer: sim time) as the column ``log_time``."""
    topics: dict[str, Topic] = {}
    with AnyReader([Path(bag)]) as reader:
        for conn, t, raw in reader.messages():
            topic = topics.setdefault(conn.topic, Topic(conn.msgtype))
            flat = {"log_time": t}
            _flatten(reader.deserialize(raw, conn.msgtype), "", flat)
            for path, value in flat.items():
                col = topic.columns.setdefault(path, Column(_is_float(value)))
                col.values.append(np.asarray(value, dtype=float) if col.floats else value)
                col.present.append(topic.count)
            topic.count += 1
    return topics


# --- scales -------------------------------------------------------------------------------------------------


def _finite_max_abs(a: np.ndarray, axis=None) -> np.ndarray:
    a = np.where(np.isfinite(a), np.abs(a), 0.0)
    return a.max(axis=axis) if a.size else np.zeros(() if axis is None else a.shape[1:])


def scale(path: str, values: list[np.ndarray]) -> np.ndarray:
    """The scale each value of a float column is compared against (broadcast over its messages): per component
    for a fixed-length field, one for a field whose length varies, S_i S_j for a square ``covariance``."""
    lengths = {np.size(v) for v in values}
    if len(lengths) != 1:
        return _finite_max_abs(np.concatenate([np.ravel(v) for v in values]))
    stacked = np.array([np.ravel(v) for v in values])
    n = math.isqrt(stacked.shape[1])
    if path.endswith("covariance") and n * n == stacked.shape[1] and n > 0:
        sigma = np.sqrt(_finite_max_abs(stacked[:, :: n + 1], axis=0))  # the diagonal's largest variances
        return np.outer(sigma, sigma).ravel()
    return _finite_max_abs(stacked, axis=0)


# --- comparison ---------------------------------------------------------------------------------------------


@dataclass
class Deviation:
    """The largest deviation of a float column, in units of its scale."""

    topic: str
    path: str
    scaled: float
    message: int


def _describe(v) -> str:
    text = np.array2string(v, threshold=8) if isinstance(v, np.ndarray) else repr(v)
    return text if len(text) < 120 else text[:117] + "..."


def compare(found: dict[str, Topic], reference: dict[str, Topic], rtol: float) -> tuple[list[str], list[Deviation]]:
    """(every difference beyond the rules above, one line each; each float column's largest deviation in units
    of its scale, largest first). ``reference`` gives the scales."""
    problems: list[str] = []
    deviations: list[Deviation] = []
    if sorted(found) != sorted(reference):
        problems.append(
            f"topics differ: only found {sorted(set(found) - set(reference))}, "
            f"only in the reference {sorted(set(reference) - set(found))}"
        )
    for name in sorted(set(found) & set(reference)):
        got, ref = found[name], reference[name]
        if (got.msgtype, got.count) != (ref.msgtype, ref.count):
            problems.append(f"{name}: {got.count} {got.msgtype} messages, the reference has {ref.count} {ref.msgtype}")
            continue
        if sorted(got.columns) != sorted(ref.columns):
            problems.append(f"{name}: fields differ: {sorted(set(got.columns) ^ set(ref.columns))}")
            continue
        for path, rc in ref.columns.items():
            gc = got.columns[path]
            if gc.present != rc.present or gc.floats != rc.floats:
                problems.append(f"{name} {path}: present in other messages, or of another kind")
                continue
            if rc.floats:
                deviations.append(_compare_floats(name, path, gc, rc, rtol, problems))
            else:
                for i, a, b in zip(rc.present, gc.values, rc.values):
                    if not _same(a, b):
                        problems.append(f"{name} message {i} {path}: {_describe(a)}, the reference has {_describe(b)}")
                        break
    deviations.sort(key=lambda d: -d.scaled)
    return problems, deviations


def _same(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.shape(a) == np.shape(b) and bool(np.all(np.asarray(a) == np.asarray(b)))
    return a == b


def _compare_floats(topic: str, path: str, got: Column, ref: Column, rtol: float, problems: list[str]) -> Deviation:
    s = scale(path, ref.values)
    worst = Deviation(topic, path, 0.0, -1)
    for i, a, b in zip(ref.present, got.values, ref.values):
        a, b = np.ravel(a), np.ravel(b)
        if a.shape != b.shape:
            problems.append(f"{topic} message {i} {path}: {a.size} values, the reference has {b.size}")
            return worst
        finite = np.isfinite(b)
        if not (
            np.array_equal(np.isnan(a), np.isnan(b))
            and np.array_equal(np.isinf(a), np.isinf(b))
            and np.array_equal(a[np.isinf(b)], b[np.isinf(b)])
        ):
            problems.append(
                f"{topic} message {i} {path}: NaN/inf at other places: {_describe(a)}, the reference has {_describe(b)}"
            )
            return worst
        si = np.broadcast_to(s, b.shape)
        d = np.abs(np.where(finite, a - b, 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            scaled = np.where(d > 0, d / si, 0.0)  # a zero scale: the column is exactly zero; any change is inf
        k = int(np.argmax(scaled)) if scaled.size else 0
        if scaled.size and scaled[k] > worst.scaled:
            worst = Deviation(topic, path, float(scaled[k]), i)
        if scaled.size and scaled[k] > rtol:
            problems.append(
                f"{topic} message {i} {path}[{k}]: {a[k]!r}, the reference has {b[k]!r}: off by "
                f"{scaled[k]:.2g} of the column's scale {float(si[k]):.3g} (tolerance {rtol:g})"
            )
            return worst
    return worst


# --- storage ------------------------------------------------------------------------------------------------


def _to_float_storage(values: list[np.ndarray]) -> np.ndarray:
    return np.concatenate([np.ravel(v) for v in values]).astype(STORED_FLOAT) if values else np.zeros(0)


def save(path: Path, topics: dict[str, Topic], meta: dict) -> None:
    """Write ``topics`` as one zstd-compressed ``.npz``: per column its message indices, its values (floats as
    STORED_FLOAT, each message's length beside them) or, for other values, a JSON list; ``meta`` as JSON."""
    arrays: dict[str, np.ndarray] = {}
    index = {}
    for t, (name, topic) in enumerate(sorted(topics.items())):
        cols = {}
        for c, (p, col) in enumerate(sorted(topic.columns.items())):
            key = f"t{t}c{c}"
            cols[p] = {"key": key, "floats": col.floats}
            arrays[f"{key}.present"] = np.asarray(col.present, dtype=np.int64)
            if col.floats:
                arrays[f"{key}.values"] = _to_float_storage(col.values)
                arrays[f"{key}.sizes"] = np.asarray([np.size(v) for v in col.values], dtype=np.int64)
                arrays[f"{key}.shapes"] = np.asarray([np.ndim(v) for v in col.values], dtype=np.int64)
            else:
                arrays[f"{key}.json"] = np.frombuffer(
                    json.dumps([_jsonable(v) for v in col.values]).encode(), dtype=np.uint8
                )
        index[name] = {"msgtype": topic.msgtype, "count": topic.count, "columns": cols}
    arrays["meta.json"] = np.frombuffer(json.dumps({"meta": meta, "topics": index}).encode(), dtype=np.uint8)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    path.write_bytes(zstandard.ZstdCompressor(level=19).compress(buf.getvalue()))


def _jsonable(v):
    if isinstance(v, np.ndarray):
        return {"array": v.tolist(), "dtype": str(v.dtype)}
    if isinstance(v, (np.integer, np.bool_)):
        return v.item()
    return v


def _from_json(v):
    if isinstance(v, dict) and "array" in v:
        return np.asarray(v["array"], dtype=v["dtype"])
    return v


def load(path: Path) -> tuple[dict[str, Topic], dict]:
    """(topics, meta) of a file ``save`` wrote."""
    data = np.load(io.BytesIO(zstandard.ZstdDecompressor().decompress(path.read_bytes())), allow_pickle=False)
    head = json.loads(data["meta.json"].tobytes())
    topics = {}
    for name, entry in head["topics"].items():
        topic = Topic(entry["msgtype"], entry["count"])
        for p, c in entry["columns"].items():
            key = c["key"]
            col = Column(c["floats"], present=data[f"{key}.present"].tolist())
            if col.floats:
                flat = data[f"{key}.values"].astype(float)
                sizes, ndims = data[f"{key}.sizes"], data[f"{key}.shapes"]
                cuts = np.cumsum(sizes)[:-1]
                col.values = [v if nd else v.reshape(()) for v, nd in zip(np.split(flat, cuts), ndims)]
            else:
                col.values = [_from_json(v) for v in json.loads(data[f"{key}.json"].tobytes())]
            topic.columns[p] = col
        topics[name] = topic
    return topics, head["meta"]
