"""CCSDS Tracking Data Messages (TDM, CCSDS 503.0-B-2, version 2.0), KVN: writer and reader.

A message holds segments; each segment one tracking pass of one set of participants: metadata (TIME_SYSTEM,
PARTICIPANT_n, MODE, PATH, ANGLE_TYPE, RANGE_UNITS, ...) and data lines ``KEYWORD = epoch value`` between
DATA_START and DATA_STOP. The keywords the bench writes and reads, with their units in the file and in memory:

=======================  ================  =======  ===============================================================
keyword                  file              memory   meaning
=======================  ================  =======  ===============================================================
RANGE                    km (RANGE_UNITS)  m        one-way distance participant 1 to 2 (the radar's range)
ANGLE_1, ANGLE_2         deg               rad      azimuth (from north, clockwise) and elevation (ANGLE_TYPE AZEL)
DOPPLER_INSTANTANEOUS    km/s              m/s      instantaneous range rate
=======================  ================  =======  ===============================================================

Other data keywords are read as numbers and kept under their name, unconverted (:attr:`TdmSegment.other`).
The reader takes version 1.0 and 2.0 KVN files and reports any problem in one line naming the file and line
(kvn.CcsdsError).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench_ccsds.kvn import Cursor, Writer, epoch_text, number, parse_epoch, parse_number, read_lines

VERSION = "2.0"
SCALE = {"RANGE": 1e3, "ANGLE_1": np.pi / 180.0, "ANGLE_2": np.pi / 180.0, "DOPPLER_INSTANTANEOUS": 1e3}
"""File units -> SI for the keywords the bench writes (RANGE in km: RANGE_UNITS km, the default)."""


@dataclass
class TdmSegment:
    """One TDM segment: its metadata (keyword -> value, in file order), its comments, and its observations of the
    keywords in SCALE as (UTC ns, SI value) lists; ``other`` the rest, unconverted."""

    metadata: dict[str, str]
    observations: dict[str, list[tuple[int, float]]] = field(default_factory=dict)
    other: dict[str, list[tuple[int, float]]] = field(default_factory=dict)
    comments: list[str] = field(default_factory=list)


def write_tdm(
    path: str | Path, segments: list[TdmSegment], originator: str, created_ns: int, comments: list[str] = ()
) -> Path:
    """Write ``segments`` as one TDM (KVN); each segment's observations (converted from SI) and ``other`` keywords
    (as they are) in time order, keyword order kept per epoch."""
    w = Writer()
    w.key("CCSDS_TDM_VERS", VERSION)
    for text in comments:
        w.comment(text)
    w.key("CREATION_DATE", epoch_text(created_ns))
    w.key("ORIGINATOR", originator)
    for seg in segments:
        w.raw()
        w.raw("META_START")
        for text in seg.comments:
            w.comment(text)
        for key, value in seg.metadata.items():
            w.key(key, value)
        w.raw("META_STOP")
        w.raw()
        w.raw("DATA_START")
        streams = [*seg.observations.items(), *seg.other.items()]
        rows = sorted(
            ((epoch, order, key, value) for order, (key, values) in enumerate(streams) for epoch, value in values),
            key=lambda r: (r[0], r[1]),
        )
        for epoch, _order, key, value in rows:
            w.key(key, f"{epoch_text(epoch)} {number(value / SCALE.get(key, 1.0))}")
        w.raw("DATA_STOP")
    Path(path).write_text(w.text(), encoding="ascii")
    return Path(path)


def read_tdm(path: str | Path) -> list[TdmSegment]:
    """The segments of a TDM (KVN) file; CcsdsError naming the file and line for anything wrong."""
    path = Path(path)
    it = Cursor(path, read_lines(path))
    return it.message("TDM", ("1.0", "2.0"), _read_segment, "META_START ... META_STOP, DATA_START ... DATA_STOP")


def _read_segment(it: Cursor) -> TdmSegment:
    start = it.next("META_START")
    if start.text != "META_START":
        raise it.error(start, f"expected META_START, got {start.text[:40]!r}")
    comments = []
    metadata: dict[str, str] = {}
    while (line := it.next("META_STOP")).text != "META_STOP":
        if line.key == "COMMENT":
            comments.append(line.value)
        elif line.key is None:
            raise it.error(line, f"expected KEY = value before META_STOP, got {line.text[:40]!r}")
        elif line.key in metadata:
            raise it.error(line, f"keyword {line.key} given twice")
        else:
            metadata[line.key] = line.value
    if "TIME_SYSTEM" not in metadata or "PARTICIPANT_1" not in metadata:
        raise it.error(start, "the segment's metadata needs TIME_SYSTEM and PARTICIPANT_1")
    units = metadata.get("RANGE_UNITS", "km")
    line = it.next("DATA_START")
    if line.text != "DATA_START":
        raise it.error(line, f"expected DATA_START, got {line.text[:40]!r}")
    seg = TdmSegment(metadata, comments=comments)
    while (line := it.next("DATA_STOP")).text != "DATA_STOP":
        if line.key == "COMMENT":
            seg.comments.append(line.value)
            continue
        fields = line.value.split()
        if line.key is None or len(fields) != 2:
            raise it.error(line, "a data line is KEYWORD = epoch value")
        epoch = parse_epoch(fields[0], it.where(line))
        value = parse_number(fields[1], it.where(line))
        if line.key in SCALE:
            if line.key == "RANGE" and units != "km":
                raise it.error(line, f"RANGE in RANGE_UNITS {units}: this reader takes km")
            seg.observations.setdefault(line.key, []).append((epoch, value * SCALE[line.key]))
        else:
            seg.other.setdefault(line.key, []).append((epoch, value))
    return seg
