"""The lock-step time grid of a run, from the scenario's ``time`` section.

Sim time is seconds since the scenario's epoch. ``time.epoch`` optionally puts that epoch on the calendar: a UTC
date and time (ISO 8601, e.g. ``"2008-09-20T12:25:40.104192Z"``), which a truth from a real satellite's
elements needs (orbit_sim.tle) and which fixes the Earth's orientation at t = 0 (orbit_sim.truth.build_earth).
Sim time counts SI seconds from it without leap seconds: a run that spans a leap second is labelled one second
off after it (none has been inserted since 2017).
"""
from __future__ import annotations

import datetime as dt_
from dataclasses import dataclass

import numpy as np

from bench_engine.config import ScenarioError, Section

MAX_STEPS = 10_000_000
"""Most lock-steps a run may have (a day at 0.01 s); beyond it a typo in ``time`` is far likelier than intent."""


@dataclass(frozen=True)
class TimeGrid:
    """Lock-step grid: step k happens at t = start + k dt (integer nanoseconds, no drift)."""

    start_ns: int
    dt_ns: int
    steps: int
    pacing_window: int = 0
    """Steps (messages) the source may run ahead of its slowest consumer (bench_engine.lockstep)."""
    epoch: dt_.datetime | None = None
    """UTC date and time of t = 0 (timezone-aware, microseconds), or None when the scenario gives none."""

    @property
    def dt(self) -> float:
        return self.dt_ns * 1e-9

    def t_ns(self, k: int) -> int:
        return self.start_ns + k * self.dt_ns

    def times(self) -> np.ndarray:
        return (self.start_ns + np.arange(self.steps, dtype=np.int64) * self.dt_ns) * 1e-9


def build_time(cfg: dict) -> TimeGrid:
    """The grid of ``time``: start, dt, duration [s] (steps = duration / dt + 1), pacing_window."""
    sec = Section(cfg.get("time"), "time")
    start = sec.non_negative("start")
    dt = sec.positive("dt")
    duration = sec.positive("duration")
    window = sec.get("pacing_window", int, 0, lambda v: v >= 0, ">= 0")
    epoch = parse_epoch(sec.get("epoch", (str, dt_.datetime), None), "time.epoch")
    sec.finish()
    dt_ns = int(round(dt * 1e9))
    steps = int(round(duration / dt)) + 1
    if dt_ns < 1 or steps > MAX_STEPS:
        raise ScenarioError(f"'time.duration' / 'time.dt' = {duration:g} s / {dt:g} s gives {steps} steps; a run "
                            f"may have at most {MAX_STEPS} steps of at least 1 ns: shorten time.duration or "
                            "lengthen time.dt")
    return TimeGrid(int(round(start * 1e9)), dt_ns, steps, window, epoch)


def parse_epoch(value: str | dt_.datetime | None, key: str) -> dt_.datetime | None:
    """A UTC epoch from ISO 8601 text (``Z``, ``+00:00`` or no offset: UTC; another offset is converted) or from
    a datetime (YAML reads an unquoted timestamp as one); ScenarioError naming ``key`` when it is neither."""
    if value is None:
        return None
    if isinstance(value, str):
        try:
            value = dt_.datetime.fromisoformat(value.strip())
        except ValueError:
            raise ScenarioError(f"'{key}' must be a UTC date and time in ISO 8601, e.g. 2008-09-20T12:25:40.104192Z; "
                                f"got {value!r}") from None
    if value.tzinfo is None:
        value = value.replace(tzinfo=dt_.timezone.utc)
    value = value.astimezone(dt_.timezone.utc)
    if not 1972 <= value.year <= 2200:
        raise ScenarioError(f"'{key}' is {value.isoformat()}: the bench's UTC dates run from 1972 (integral leap "
                            "seconds) to 2200")
    return value
