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

from bench_engine.config import ScenarioError
from bench_engine.settings import NON_NEGATIVE, POSITIVE, Settings, read, setting

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


@dataclass(frozen=True, kw_only=True)
class Time(Settings):
    """The scenario's ``time`` section."""

    start: float = setting(unit="s", doc="sim time of step 0 (since the scenario's epoch)", check=NON_NEGATIVE)
    dt: float = setting(unit="s", doc="the lock-step period: one truth sample per step", check=POSITIVE)
    duration: float = setting(unit="s", doc="the run's length: duration / dt + 1 steps", check=POSITIVE)
    pacing_window: int = setting(
        0,
        doc="messages the source may run ahead of its slowest consumer (bench_engine.lockstep; 0: strict lock-step)",
        check=NON_NEGATIVE,
    )
    epoch: str | dt_.datetime | None = setting(
        None,
        doc="the UTC date and time of t = 0, ISO 8601 (e.g. 2008-09-20T12:25:40.104192Z): what a truth from a "
        "real satellite's elements needs, and the Earth's orientation at t = 0 (null: no calendar date)",
    )

    @property
    def steps(self) -> int:
        return int(round(self.duration / self.dt)) + 1

    def validate(self, path: str) -> None:
        parse_epoch(self.epoch, f"{path}.epoch")
        if int(round(self.dt * 1e9)) < 1 or self.steps > MAX_STEPS:
            raise ScenarioError(
                f"'{path}.duration' / '{path}.dt' = {self.duration:g} s / {self.dt:g} s gives "
                f"{self.steps} steps; a run may have at most {MAX_STEPS} steps of at least 1 ns: "
                f"shorten {path}.duration or lengthen {path}.dt"
            )


def build_time(cfg: dict) -> TimeGrid:
    """The grid of the scenario's ``time`` section (:class:`Time`)."""
    t = read(Time, cfg.get("time"), "time")
    return TimeGrid(
        int(round(t.start * 1e9)), int(round(t.dt * 1e9)), t.steps, t.pacing_window, parse_epoch(t.epoch, "time.epoch")
    )


def parse_epoch(value: str | dt_.datetime | None, key: str) -> dt_.datetime | None:
    """A UTC epoch from ISO 8601 text (``Z``, ``+00:00`` or no offset: UTC; another offset is converted) or from
    a datetime (YAML reads an unquoted timestamp as one); ScenarioError naming ``key`` when it is neither."""
    if value is None:
        return None
    if isinstance(value, str):
        try:
            value = dt_.datetime.fromisoformat(value.strip())
        except ValueError:
            raise ScenarioError(
                f"'{key}' must be a UTC date and time in ISO 8601, e.g. 2008-09-20T12:25:40.104192Z; got {value!r}"
            ) from None
    if value.tzinfo is None:
        value = value.replace(tzinfo=dt_.UTC)
    value = value.astimezone(dt_.UTC)
    if not 1972 <= value.year <= 2200:
        raise ScenarioError(
            f"'{key}' is {value.isoformat()}: the bench's UTC dates run from 1972 (integral leap seconds) to 2200"
        )
    return value
