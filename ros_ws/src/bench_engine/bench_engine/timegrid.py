"""The lock-step time grid of a run, from the scenario's ``time`` section."""
from __future__ import annotations

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
    sec.finish()
    dt_ns = int(round(dt * 1e9))
    steps = int(round(duration / dt)) + 1
    if dt_ns < 1 or steps > MAX_STEPS:
        raise ScenarioError(f"'time.duration' / 'time.dt' = {duration:g} s / {dt:g} s gives {steps} steps; a run "
                            f"may have at most {MAX_STEPS} steps of at least 1 ns: shorten time.duration or "
                            "lengthen time.dt")
    return TimeGrid(int(round(start * 1e9)), dt_ns, steps, window)
