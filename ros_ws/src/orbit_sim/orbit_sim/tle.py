"""Two-line element sets (TLEs) and their SGP4 propagation: the truth of a real, catalogued satellite.

An element set is read from its two lines (optionally after a title line) and checked as a hostile input
would need: printable ASCII, 69 columns, line numbers, one catalogue number, each line's modulo-10 checksum
(digits count their value, a minus sign one), then the fields as ``sgp4`` parses them. Every problem is a
:class:`TleError`, one line naming where the lines came from and what is wrong.

Propagation is ``sgp4``'s (Vallado's SGP4/SDP4, the reference implementation of Hoots & Roehrich's Spacetrack
Report #3 as revised by Vallado et al. 2006, with the WGS-72 constants the element sets are fitted with). Its
output frame is TEME (true equator, mean equinox); with the scenario's calendar epoch the bench's ``eci`` is
TEME and its ECEF the pseudo-Earth-fixed frame, R3(GMST) TEME (orbit_sim.frames states the conversion and what
it leaves out).

The truth model ``sgp4`` (entry-point group ``tracking_bench.truth_models``) reads ``truth.tle`` (the lines, a
list of two strings, or three with the title first) or ``truth.tle_file`` (a file holding one element set), and
needs ``time.epoch``: sim time t is propagated at tsince = (time.epoch - the element set's epoch) + t.
"""

from __future__ import annotations

import datetime as dt_
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from sgp4.api import WGS72, Satrec

from bench_engine.config import ScenarioError
from bench_engine.labels import ORBIT
from bench_engine.timegrid import TimeGrid
from orbit_sim.frames import julian_date
from orbit_sim.truth import Sgp4, Truth

LINE_LENGTH = 69
MAX_FILE_BYTES = 64 * 1024
"""A TLE file holds one element set of three short lines; anything much larger is not one."""
SGP4_ERRORS = {
    1: "its mean eccentricity left [0, 1)",
    2: "its mean motion became negative",
    3: "its perturbed eccentricity left [0, 1]",
    4: "its semi-latus rectum became negative",
    5: "(unused error code 5)",
    6: "the satellite decayed (its orbit is below the Earth's surface)",
}
"""sgp4's error codes (sgp4.api.SGP4_ERRORS says the same in its words)."""


class TleError(ValueError):
    """A two-line element set that cannot be used: one line naming where it came from and what is wrong."""


def checksum(line: str) -> int:
    """The modulo-10 checksum of a TLE line's first 68 columns: digits their value, '-' one, others zero."""
    return sum(int(c) if c.isdigit() else 1 if c == "-" else 0 for c in line[:68]) % 10


@dataclass(frozen=True)
class ElementSet:
    """One checked element set: its title (may be empty), its two lines and where they were read."""

    title: str
    line1: str
    line2: str
    where: str

    @property
    def catalogue_number(self) -> str:
        return self.line1[2:7].strip()

    def satrec(self) -> Satrec:
        return Satrec.twoline2rv(self.line1, self.line2, WGS72)

    @property
    def epoch(self) -> dt_.datetime:
        """The element set's epoch, UTC (whole microseconds: a TLE gives the day to 1e-8, 864 µs)."""
        sat = self.satrec()
        days = (sat.jdsatepoch - 2440587.5) + sat.jdsatepochF
        us = round(days * 86400e6)
        return dt_.datetime(1970, 1, 1, tzinfo=dt_.UTC) + dt_.timedelta(microseconds=us)

    def states(self, epoch: dt_.datetime, times: np.ndarray) -> np.ndarray:
        """TEME states [x y z vx vy vz] (m, m/s), one row per time [s after ``epoch``]; TleError when SGP4 fails
        at one of them (naming the first such time and why)."""
        times = np.asarray(times, dtype=float)
        jd, fraction = julian_date(epoch)
        sat = self.satrec()
        errors, r, v = sat.sgp4_array(np.full(times.shape, jd), fraction + times / 86400.0)
        bad = np.flatnonzero(errors)
        if bad.size:
            k = int(bad[0])
            code = int(errors[k])
            raise TleError(
                f"{self.where}: SGP4 fails {times[k]:g} s after {epoch.isoformat()}: "
                f"{SGP4_ERRORS.get(code, f'error code {code}')}"
            )
        states = np.hstack((r, v)) * 1e3
        if not np.all(np.isfinite(states)):
            raise TleError(f"{self.where}: SGP4 gives non-finite states for these elements")
        return states


def read_tle(lines: list[str], where: str) -> ElementSet:
    """An element set from its lines (two, or three with a title first); TleError naming ``where``."""
    if not isinstance(lines, (list, tuple)) or not all(isinstance(line, str) for line in lines):
        raise TleError(f"{where}: an element set is a list of its lines (two, or a title and two), as strings")
    lines = [line.rstrip("\r\n").rstrip() for line in lines]
    lines = [line for line in lines if line]
    if len(lines) not in (2, 3):
        raise TleError(
            f"{where}: an element set has two lines (or a title and two); found {len(lines)} non-empty lines"
        )
    title = lines[0].strip() if len(lines) == 3 else ""
    if title.startswith("0 "):
        title = title[2:].strip()  # the three-line format's title marker
    line1, line2 = lines[-2:]
    for number, line in ((1, line1), (2, line2)):
        _check_line(line, number, where)
    if line1[2:7] != line2[2:7]:
        raise TleError(
            f"{where}: the two lines name different satellites ({line1[2:7].strip()!r} and {line2[2:7].strip()!r})"
        )
    tle = ElementSet(title, line1, line2, where)
    try:
        sat = tle.satrec()
    except (ValueError, RuntimeError) as err:
        raise TleError(f"{where}: sgp4 cannot read these elements ({' '.join(str(err).split())[:200]})") from None
    if sat.error:
        raise TleError(
            f"{where}: sgp4 rejects these elements at their epoch: "
            f"{SGP4_ERRORS.get(int(sat.error), f'error code {sat.error}')}"
        )
    if not 0.0 < sat.no_kozai < 2.0 * np.pi / 60.0:  # rad/min: at most one revolution a minute
        raise TleError(f"{where}: line 2's mean motion {sat.no_kozai * 1440 / (2 * np.pi):g} rev/day is not an orbit")
    return tle


def _check_line(line: str, number: int, where: str) -> None:
    if not line.isascii() or not line.isprintable():
        raise TleError(f"{where}: line {number} holds characters other than printable ASCII")
    if len(line) != LINE_LENGTH:
        raise TleError(f"{where}: line {number} has {len(line)} columns; a TLE line has {LINE_LENGTH}")
    if not line.startswith(f"{number} "):
        raise TleError(f"{where}: line {number} must start with '{number} ', got {line[:2]!r}")
    if not line[68].isdigit() or int(line[68]) != checksum(line):
        raise TleError(
            f"{where}: line {number}'s checksum is {line[68]!r}; its columns 1-68 give {checksum(line)} "
            "(a mistyped or damaged element set)"
        )


def read_tle_file(path: str | Path) -> ElementSet:
    """The one element set in a text file (two lines, or a title and two); TleError naming the file."""
    path = Path(path)
    try:
        with open(path, "rb") as f:
            raw = f.read(MAX_FILE_BYTES + 1)
    except OSError as err:
        raise TleError(f"{path}: cannot be read ({err.strerror or err})") from None
    if len(raw) > MAX_FILE_BYTES:
        raise TleError(f"{path}: larger than {MAX_FILE_BYTES} bytes; a TLE file holds one element set")
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError:
        raise TleError(f"{path}: not ASCII text (a TLE file is)") from None
    return read_tle(text.splitlines(), str(path))


def element_set(sec: Sgp4) -> ElementSet:
    """The element set of the ``truth`` section's keys (orbit_sim.truth.Sgp4): ``tle`` (its lines) or
    ``tle_file`` (a path)."""
    try:
        if sec.tle is not None:
            return read_tle(sec.tle, f"'{sec.where('tle')}'")
        return read_tle_file(sec.tle_file)
    except TleError as err:
        raise ScenarioError(str(err)) from None


def tle_truth(sec: Sgp4, model: str, earth, grid: TimeGrid, seed: int = 0) -> Truth:
    """The ``sgp4`` truth model: the element set's TEME states on the grid (frame ``eci``)."""
    tle = element_set(sec)
    if grid.epoch is None:
        raise ScenarioError(
            f"truth model '{model}' needs a calendar epoch: set 'time.epoch' (UTC), e.g. the element "
            f"set's own, {tle.epoch.strftime('%Y-%m-%dT%H:%M:%S.%fZ')}"
        )
    try:
        states = tle.states(grid.epoch, grid.times())
    except TleError as err:
        raise ScenarioError(str(err)) from None
    return Truth(grid, states, ORBIT, "eci")
