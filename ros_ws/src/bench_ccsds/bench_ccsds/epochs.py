"""A run's sim time on the UTC calendar, and the CCSDS names of the bench's frames.

Sim time is seconds since the scenario's epoch. With ``time.epoch`` that epoch is a UTC date, the Earth's angle
at it is its sidereal time, the bench's ``eci`` is TEME and its ECEF the pseudo-Earth-fixed frame
(orbit_sim.frames). A scenario without a date (the published studies: the papers give none) has only
``earth.theta0_deg``: its t = 0 is placed at the **nominal epoch**, the first UTC instant from
2000-01-01T12:00:00 on whose Greenwich mean sidereal time is theta0 (to 1e-13 rad). There too, then, ``eci`` is
TEME and ECEF is PEF, and an exported station sees the satellite where the bench did; every message says which
epoch it is on. CCSDS time system: UTC (sim time counts SI seconds without leap seconds: bench_engine.timegrid).
"""

from __future__ import annotations

import datetime as dt_
from dataclasses import dataclass

import numpy as np

from bench_ccsds.kvn import NS_PER_DAY, epoch_text, utc_ns
from bench_engine.timegrid import build_time
from orbit_sim.frames import GMST_RATE, JD_UNIX_EPOCH, gmst82
from orbit_sim.truth import build_earth

NOMINAL_FROM = dt_.datetime(2000, 1, 1, 12, tzinfo=dt_.UTC)
"""The nominal epoch is the first instant from here on whose GMST is the scenario's theta0."""
FRAMES = {"eci": "TEME"}
"""The bench's frame names that CCSDS names (REF_FRAME): eci is TEME on the calendar (module docstring). lvlh (a
deputy relative to its chief) and star-tracker frames have no OEM reference frame."""
TIME_SYSTEM = "UTC"


@dataclass(frozen=True)
class RunTime:
    """Where t = 0 of a run lies: UTC nanoseconds since 1970, and whether that is the nominal epoch."""

    epoch_ns: int
    nominal: bool

    def utc(self, t_ns: int) -> int:
        """Sim time [ns] -> UTC nanoseconds since 1970."""
        return self.epoch_ns + int(t_ns)

    def sim(self, utc: int) -> int:
        """UTC nanoseconds since 1970 -> sim time [ns]."""
        return int(utc) - self.epoch_ns

    def note(self) -> str:
        """What a message says about its time line."""
        if self.nominal:
            return (
                f"the scenario has no calendar epoch: its t = 0 is placed at the nominal epoch "
                f"{epoch_text(self.epoch_ns)} UTC, the first instant from 2000-01-01T12:00:00 whose GMST "
                "(IAU-82) is the scenario's earth.theta0; t = 0 + sim time in SI seconds"
            )
        return f"t = 0 of the run is its time.epoch, {epoch_text(self.epoch_ns)} UTC"


def run_time(cfg: dict) -> RunTime:
    """The run's time line from its scenario (``time.epoch``, else the nominal epoch of ``earth.theta0``)."""
    epoch = build_time(cfg).epoch
    if epoch is not None:
        return RunTime(utc_ns(epoch), False)
    return RunTime(nominal_epoch(build_earth(cfg).theta0), True)


def nominal_epoch(theta0: float) -> int:
    """UTC nanoseconds of the first instant from NOMINAL_FROM whose GMST (UT1 = UTC) is ``theta0`` [rad]."""
    start = utc_ns(NOMINAL_FROM)
    ns = start + int(round(np.mod(theta0 - _gmst(start), 2 * np.pi) / GMST_RATE * 1e9))
    for _ in range(2):  # GMST's rate is not quite constant (its T^2 term): Newton steps to 1e-13 rad
        ns += int(round((np.mod(theta0 - _gmst(ns) + np.pi, 2 * np.pi) - np.pi) / GMST_RATE * 1e9))
    return ns


def _gmst(ns: int) -> float:
    days, rest = divmod(ns, NS_PER_DAY)
    return gmst82(JD_UNIX_EPOCH + days, rest / NS_PER_DAY)


def ccsds_frame(frame_id: str) -> str | None:
    """The CCSDS REF_FRAME of a bench frame, None when CCSDS has none for it."""
    return FRAMES.get(frame_id)
