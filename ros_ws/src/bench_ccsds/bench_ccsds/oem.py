"""CCSDS Orbit Ephemeris Messages (OEM, CCSDS 502.0-B-2, version 2.0), KVN: writer and reader.

A message holds segments; each segment one object's ephemeris in one frame and time system: metadata
(OBJECT_NAME, OBJECT_ID, CENTER_NAME, REF_FRAME, TIME_SYSTEM, START_TIME, STOP_TIME), data lines
``epoch x y z vx vy vz [ax ay az]`` (km, km/s, km/s^2) and optional covariance blocks (COVARIANCE_START:
EPOCH, COV_REF_FRAME, the lower triangle of the 6x6 position-velocity covariance in km^2, km^2/s, km^2/s^2,
COVARIANCE_STOP). In memory everything is SI (m, m/s, m/s^2) and times are UTC nanoseconds since 1970
(bench_ccsds.kvn).

The reader takes version 1.0 to 3.0 KVN files, checks what it uses (required keywords, numbers, strictly
increasing epochs inside START_TIME..STOP_TIME, whole covariance triangles) and reports any problem in one line
naming the file and line (kvn.CcsdsError).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench_ccsds.kvn import Cursor, Writer, epoch_text, number, parse_epoch, parse_number, read_lines

VERSION = "2.0"
REQUIRED = ("OBJECT_NAME", "OBJECT_ID", "CENTER_NAME", "REF_FRAME", "TIME_SYSTEM", "START_TIME", "STOP_TIME")
METADATA_KEYS = set(REQUIRED) | {
    "REF_FRAME_EPOCH",
    "USEABLE_START_TIME",
    "USEABLE_STOP_TIME",
    "INTERPOLATION",
    "INTERPOLATION_DEGREE",
    "COMMENT",
}
LOWER = np.tril_indices(6)


@dataclass
class Segment:
    """One OEM segment in SI units: ``states`` (K, 6) or (K, 9) at ``epochs`` (K UTC ns); ``covariances`` a list of
    (UTC ns, 6x6) with their frame ``covariance_frame`` (None: REF_FRAME)."""

    object_name: str
    object_id: str
    frame: str
    epochs: list[int]
    states: np.ndarray
    center: str = "EARTH"
    time_system: str = "UTC"
    covariances: list[tuple[int, np.ndarray]] = field(default_factory=list)
    covariance_frame: str | None = None
    comments: list[str] = field(default_factory=list)
    interpolation: tuple[str, int] | None = None


def write_oem(
    path: str | Path, segments: list[Segment], originator: str, created_ns: int, comments: list[str] = ()
) -> Path:
    """Write ``segments`` as one OEM (KVN) at ``path``."""
    w = Writer()
    w.key("CCSDS_OEM_VERS", VERSION)
    for text in comments:
        w.comment(text)
    w.key("CREATION_DATE", epoch_text(created_ns))
    w.key("ORIGINATOR", originator)
    for seg in segments:
        w.raw()
        _write_segment(w, seg)
    Path(path).write_text(w.text(), encoding="ascii")
    return Path(path)


def _write_segment(w: Writer, seg: Segment) -> None:
    w.raw("META_START")
    for text in seg.comments:
        w.comment(text)
    for key, value in (
        ("OBJECT_NAME", seg.object_name),
        ("OBJECT_ID", seg.object_id),
        ("CENTER_NAME", seg.center),
        ("REF_FRAME", seg.frame),
        ("TIME_SYSTEM", seg.time_system),
        ("START_TIME", epoch_text(seg.epochs[0])),
        ("STOP_TIME", epoch_text(seg.epochs[-1])),
    ):
        w.key(key, value)
    if seg.interpolation is not None:
        w.key("INTERPOLATION", seg.interpolation[0])
        w.key("INTERPOLATION_DEGREE", str(seg.interpolation[1]))
    w.raw("META_STOP")
    w.raw()
    km = np.asarray(seg.states, dtype=float) / 1e3
    for epoch, row in zip(seg.epochs, km):
        w.raw(" ".join([epoch_text(epoch), *map(number, row)]))
    if seg.covariances:
        w.raw()
        w.raw("COVARIANCE_START")
        for epoch, cov in seg.covariances:
            w.key("EPOCH", epoch_text(epoch))
            w.key("COV_REF_FRAME", seg.covariance_frame or seg.frame)
            cov_km = np.asarray(cov, dtype=float) / 1e6
            for i in range(6):
                w.raw(" ".join(number(v) for v in cov_km[i, : i + 1]))
        w.raw("COVARIANCE_STOP")


def read_oem(path: str | Path) -> list[Segment]:
    """The segments of an OEM (KVN) file in SI units; CcsdsError naming the file and line for anything wrong."""
    path = Path(path)
    lines = read_lines(path)
    it = Cursor(path, lines)
    return it.message("OEM", ("1.0", "2.0", "3.0"), _read_segment, "META_START ... META_STOP and data lines")


def _read_segment(it: Cursor) -> Segment:
    start = it.next("META_START")
    if start.text != "META_START":
        raise it.error(start, f"expected META_START, got {start.text[:40]!r}")
    meta = it.keys_until("META_STOP", METADATA_KEYS, inclusive=True)
    missing = [k for k in REQUIRED if k not in meta]
    if missing:
        raise it.error(start, f"the segment's metadata lacks {', '.join(missing)}")
    window = (
        parse_epoch(meta["START_TIME"].value, it.where(meta["START_TIME"])),
        parse_epoch(meta["STOP_TIME"].value, it.where(meta["STOP_TIME"])),
    )
    epochs: list[int] = []
    rows: list[list[float]] = []
    covariances: list[tuple[int, np.ndarray]] = []
    cov_frame = None
    while (line := it.peek()) is not None and line.text != "META_START":
        it.next("")
        if line.key == "COMMENT":
            continue
        if line.text == "COVARIANCE_START":
            cov_frame = _read_covariances(it, covariances, cov_frame)
            continue
        if line.key is not None:
            raise it.error(line, f"keyword {line.key} is not allowed among the data lines")
        fields = line.text.split()
        if len(fields) not in (7, 10):
            raise it.error(line, f"a data line is an epoch and 6 or 9 numbers; it has {len(fields)} fields")
        if rows and len(fields) - 1 != len(rows[0]):
            raise it.error(line, "a segment's data lines all have accelerations or none")
        epoch = parse_epoch(fields[0], it.where(line))
        if epochs and epoch <= epochs[-1]:
            raise it.error(line, f"epoch {fields[0]} is not after the one before")
        if not window[0] <= epoch <= window[1]:
            raise it.error(line, f"epoch {fields[0]} lies outside START_TIME..STOP_TIME")
        epochs.append(epoch)
        rows.append([parse_number(v, it.where(line)) for v in fields[1:]])
    if not epochs:
        raise it.error(start, "the segment has no data lines")
    return Segment(
        meta["OBJECT_NAME"].value,
        meta["OBJECT_ID"].value,
        meta["REF_FRAME"].value,
        epochs,
        np.array(rows) * 1e3,
        center=meta["CENTER_NAME"].value,
        time_system=meta["TIME_SYSTEM"].value,
        covariances=covariances,
        covariance_frame=cov_frame,
    )


def _read_covariances(it: Cursor, out: list, frame: str | None) -> str | None:
    """Covariance blocks up to COVARIANCE_STOP, appended to ``out`` (SI); returns the COV_REF_FRAME seen."""
    while True:
        line = it.next("COVARIANCE_STOP")
        if line.text == "COVARIANCE_STOP":
            return frame
        if line.key == "COMMENT":
            continue
        if line.key != "EPOCH":
            raise it.error(line, f"a covariance block starts with EPOCH, got {line.text[:40]!r}")
        epoch = parse_epoch(line.value, it.where(line))
        nxt = it.peek()
        if nxt is not None and nxt.key == "COV_REF_FRAME":
            frame = it.next("").value
        values = []
        for row in range(6):
            line = it.next("a covariance row")
            fields = line.text.split()
            if line.key is not None or len(fields) != row + 1:
                raise it.error(line, f"covariance row {row + 1} holds {row + 1} numbers (the lower triangle)")
            values += [parse_number(v, it.where(line)) for v in fields]
        cov = np.zeros((6, 6))
        cov[LOWER] = values
        cov = cov + np.tril(cov, -1).T
        out.append((epoch, cov * 1e6))
