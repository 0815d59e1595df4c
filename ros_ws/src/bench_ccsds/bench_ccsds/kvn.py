"""CCSDS KVN (keyword = value notation) text: the lexical layer the OEM and TDM readers and writers share.

Writing: numbers with 17 significant digits (:func:`number`: the nearest double of the written decimal is the
double that was written, so a value read back is the one exported), epochs as ``YYYY-MM-DDThh:mm:ss.fffffffff``
(:func:`epoch_text`: nanoseconds, the resolution of a bag's stamps), one keyword per line.

Reading assumes a hostile file (:func:`read_lines`): at most MAX_BYTES, ASCII, lines of at most MAX_LINE
characters, numbers matching the CCSDS numeric syntax (no NaN, no infinity, nothing Python's ``float`` accepts
beyond it such as ``1_0``), epochs in either CCSDS calendar form (``YYYY-MM-DDThh:mm:ss[.f]`` or day of year
``YYYY-DDDThh:mm:ss[.f]``, an optional ``Z``) between 1972 and 2200, no leap second. Every problem is a
:class:`CcsdsError`: one line naming the file, the line and what is wrong.

Absolute times are integers: nanoseconds of UTC since 1970-01-01T00:00:00, days of 86400 s (a leap second has
no reading, as in POSIX time).
"""

from __future__ import annotations

import datetime as dt_
import re
from dataclasses import dataclass
from pathlib import Path

MAX_BYTES = 256 << 20
"""Largest message read (256 MiB: a day of 10 Hz covariances is ~100 MiB)."""
MAX_LINE = 4096
"""Longest line read (CCSDS lines are short: a covariance row is ~150 characters)."""
NS_PER_DAY = 86_400_000_000_000
UNIX_DAY0 = dt_.date(1970, 1, 1).toordinal()
YEARS = (1972, 2200)

NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")
EPOCH = re.compile(r"^(\d{4})-(?:(\d{2})-(\d{2})|(\d{3}))T(\d{2}):(\d{2}):(\d{2})(?:\.(\d+))?Z?$")
KEYWORD = re.compile(r"^[A-Z][A-Z0-9_]*$")


class CcsdsError(ValueError):
    """A CCSDS message that cannot be read: one line naming the file, the line and the problem."""


@dataclass(frozen=True)
class Line:
    """One non-blank line: its number (1-based), its text stripped, and for ``KEY = value`` lines the keyword
    and value (for other lines ``key`` is None). COMMENT lines have key ``COMMENT`` and the rest as value."""

    number: int
    text: str
    key: str | None
    value: str


def number(value: float) -> str:
    """A float as CCSDS KVN writes it here: 17 significant digits, exponent form (round-trips the double)."""
    return f"{float(value):.16e}"


def epoch_text(utc_ns: int) -> str:
    """UTC nanoseconds since 1970 -> ``YYYY-MM-DDThh:mm:ss.fffffffff``."""
    days, ns = divmod(int(utc_ns), NS_PER_DAY)
    date = dt_.date.fromordinal(UNIX_DAY0 + days)
    seconds, fraction = divmod(ns, 1_000_000_000)
    hours, rest = divmod(seconds, 3600)
    return f"{date.isoformat()}T{hours:02d}:{rest // 60:02d}:{rest % 60:02d}.{fraction:09d}"


def utc_ns(epoch: dt_.datetime) -> int:
    """A timezone-aware datetime -> UTC nanoseconds since 1970 (exact: a datetime holds microseconds)."""
    delta = epoch.astimezone(dt_.UTC) - dt_.datetime(1970, 1, 1, tzinfo=dt_.UTC)
    return (delta.days * 86_400 + delta.seconds) * 1_000_000_000 + delta.microseconds * 1000


def parse_epoch(text: str, where: str) -> int:
    """A CCSDS epoch (calendar or day-of-year form, UTC reading) -> nanoseconds since 1970; CcsdsError naming
    ``where`` for anything else. Digits beyond nanoseconds are rounded."""
    m = EPOCH.match(text.strip())
    if not m:
        raise CcsdsError(
            f"{where}: {_shown(text)} is not a CCSDS epoch (YYYY-MM-DDThh:mm:ss[.f] or YYYY-DDDThh:mm:ss[.f])"
        )
    year, month, day, doy, hh, mm, ss, fraction = m.groups()
    year = int(year)
    if not YEARS[0] <= year <= YEARS[1]:
        raise CcsdsError(f"{where}: epoch {text.strip()} is outside {YEARS[0]}-{YEARS[1]}")
    try:
        if doy is not None:
            date = dt_.date(year, 1, 1) + dt_.timedelta(days=int(doy) - 1)
            if date.year != year or int(doy) < 1:
                raise ValueError
        else:
            date = dt_.date(year, int(month), int(day))
    except ValueError:
        raise CcsdsError(f"{where}: epoch {text.strip()} names no calendar day") from None
    hh, mm, ss = int(hh), int(mm), int(ss)
    if ss == 60:
        raise CcsdsError(f"{where}: epoch {text.strip()} is a leap second, which the bench's time line has not")
    if hh > 23 or mm > 59 or ss > 59:
        raise CcsdsError(f"{where}: epoch {text.strip()} is not a time of day")
    digits = (fraction or "")[:10].ljust(10, "0")
    ns = (int(digits) + 5) // 10  # rounded to the nanosecond
    return (date.toordinal() - UNIX_DAY0) * NS_PER_DAY + ((hh * 60 + mm) * 60 + ss) * 1_000_000_000 + ns


def parse_number(text: str, where: str) -> float:
    """A CCSDS number (finite decimal or exponent form); CcsdsError naming ``where`` for anything else."""
    text = text.strip()
    if not NUMBER.match(text):
        raise CcsdsError(f"{where}: {_shown(text)} is not a number")
    value = float(text)
    if value != value or abs(value) == float("inf"):
        raise CcsdsError(f"{where}: {_shown(text)} is out of a double's range")
    return value


def read_lines(path: str | Path) -> list[Line]:
    """The non-blank lines of a KVN file, tokenised; CcsdsError naming the file for anything not KVN text."""
    path = Path(path)
    try:
        with open(path, "rb") as f:
            raw = f.read(MAX_BYTES + 1)
    except OSError as err:
        raise CcsdsError(f"{path}: cannot be read ({err.strerror or err})") from None
    if len(raw) > MAX_BYTES:
        raise CcsdsError(f"{path}: larger than {MAX_BYTES} bytes, the most this reader takes")
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError as err:
        raise CcsdsError(
            f"{path}: byte {err.start} is not ASCII: a KVN message is ASCII text (an XML message or a binary file?)"
        ) from None
    if text.lstrip().startswith("<"):
        raise CcsdsError(f"{path}: an XML message: this reader takes the KVN form (CCSDS_..._VERS = ... lines)")
    lines = []
    for n, line in enumerate(text.split("\n"), start=1):
        line = line.rstrip("\r").strip()
        if not line:
            continue
        if len(line) > MAX_LINE:
            raise CcsdsError(f"{path}: line {n} has {len(line)} characters; at most {MAX_LINE} are read")
        if not line.isprintable():
            raise CcsdsError(f"{path}: line {n} holds control characters")
        if line.startswith("COMMENT"):
            lines.append(Line(n, line, "COMMENT", line[7:].strip()))
        elif "=" in line:
            key, value = (part.strip() for part in line.split("=", 1))
            if not KEYWORD.match(key):
                raise CcsdsError(f"{path}: line {n}: {_shown(key)} is not a KVN keyword")
            lines.append(Line(n, line, key, value))
        else:
            lines.append(Line(n, line, None, line))
    return lines


def _shown(text: str) -> str:
    """Text quoted for a message, cut to 40 characters."""
    return repr(text if len(text) <= 40 else text[:37] + "...")


class Writer:
    """Builds a KVN message line by line."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    def key(self, key: str, value: str) -> None:
        self.lines.append(f"{key} = {value}")

    def comment(self, text: str) -> None:
        for part in text.splitlines() or [""]:
            self.lines.append(f"COMMENT {part}".rstrip())

    def raw(self, line: str = "") -> None:
        self.lines.append(line)

    def text(self) -> str:
        return "\n".join(self.lines) + "\n"


class Cursor:
    """Walks a message's lines, with errors naming the file and line."""

    def __init__(self, path: Path, lines: list[Line]) -> None:
        self.path, self.lines, self.i = path, lines, 0

    def peek(self) -> Line | None:
        return self.lines[self.i] if self.i < len(self.lines) else None

    def next(self, expected: str) -> Line:
        if self.i >= len(self.lines):
            raise CcsdsError(f"{self.path}: the message ends where {expected} is expected (truncated?)")
        self.i += 1
        return self.lines[self.i - 1]

    def where(self, line: Line) -> str:
        return f"{self.path}: line {line.number}"

    def error(self, line: Line, text: str) -> CcsdsError:
        return CcsdsError(f"{self.where(line)}: {text}")

    def keys_until(self, stop: str, allowed, inclusive: bool = False) -> dict[str, Line]:
        """``KEY = value`` lines up to the line ``stop`` (consumed when ``inclusive``), each key once, each allowed."""
        found: dict[str, Line] = {}
        while True:
            line = self.peek()
            if line is None:
                raise CcsdsError(f"{self.path}: the message ends before {stop} (truncated?)")
            if line.text == stop:
                if inclusive:
                    self.i += 1
                return found
            self.i += 1
            if line.key == "COMMENT":
                continue
            if line.key is None:
                raise self.error(line, f"expected KEY = value before {stop}, got {line.text[:40]!r}")
            if line.key not in allowed:
                raise self.error(line, f"keyword {line.key} does not belong here (before {stop})")
            if line.key in found:
                raise self.error(line, f"keyword {line.key} given twice")
            found[line.key] = line

    def message(self, kind: str, versions: tuple[str, ...], read_segment, layout: str) -> list:
        """A whole message: its version line (``CCSDS_<kind>_VERS``, one of ``versions``), its header (CREATION_DATE
        and ORIGINATOR required) and at least one segment, each read by ``read_segment(cursor)``; ``layout`` says
        what a segment holds, for the error of a message without one."""
        first = self.next("the message header")
        if first.key != f"CCSDS_{kind}_VERS":
            raise self.error(first, f"a {kind} starts with CCSDS_{kind}_VERS (is this a {kind} in KVN?)")
        if first.value not in versions:
            raise self.error(
                first, f"CCSDS_{kind}_VERS {first.value!r}: this reader takes versions {', '.join(versions)}"
            )
        header = self.keys_until("META_START", ("CREATION_DATE", "ORIGINATOR", "MESSAGE_ID", "COMMENT"))
        for key in ("CREATION_DATE", "ORIGINATOR"):
            if key not in header:
                raise CcsdsError(f"{self.path}: the header lacks {key}")
        segments = []
        while self.peek() is not None:
            segments.append(read_segment(self))
        if not segments:
            raise CcsdsError(f"{self.path}: no segment ({layout})")
        return segments
