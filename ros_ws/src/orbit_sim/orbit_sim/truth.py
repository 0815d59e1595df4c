"""Ground truth of a run, built from the scenario's ``earth``, ``time`` and ``truth`` sections.

The whole trajectory is integrated up front with Cowell's method (``cowell.propagate``, solve_ivp at tight
tolerances) and sampled on the run's step grid; the truth node then only publishes rows.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from orbit_sim import cowell, kepler
from orbit_sim.config import Section
from orbit_sim.constants import J2_EARTH, MU_EARTH, OMEGA_EARTH, R_EARTH

TRUTH_MODELS = ("cowell_j2", "cowell_twobody")
ORBIT_LABELS = ("x", "y", "z", "vx", "vy", "vz")


@dataclass(frozen=True)
class Earth:
    """Earth model shared by truth, sensors and filters (they must agree on ECI <-> ECEF)."""

    mu: float = MU_EARTH
    j2: float = J2_EARTH
    re: float = R_EARTH
    rotation_rate: float = OMEGA_EARTH
    theta0: float = 0.0  # Earth rotation angle at the epoch [rad]


@dataclass(frozen=True)
class TimeGrid:
    """Lock-step grid: step k happens at t = start + k dt (integer nanoseconds, no drift)."""

    start_ns: int
    dt_ns: int
    steps: int

    @property
    def dt(self) -> float:
        return self.dt_ns * 1e-9

    def t_ns(self, k: int) -> int:
        return self.start_ns + k * self.dt_ns

    def times(self) -> np.ndarray:
        return (self.start_ns + np.arange(self.steps, dtype=np.int64) * self.dt_ns) * 1e-9


@dataclass
class Truth:
    grid: TimeGrid
    states: np.ndarray  # (steps, n)
    labels: tuple[str, ...]
    frame: str


def build_earth(cfg: dict) -> Earth:
    sec = Section(cfg.get("earth"), "earth")
    earth = Earth(mu=sec.positive("mu", MU_EARTH), j2=sec.get("j2", float, J2_EARTH),
                  re=sec.positive("re", R_EARTH), rotation_rate=sec.get("rotation_rate", float, OMEGA_EARTH),
                  theta0=np.radians(sec.get("theta0_deg", float, 0.0)))
    sec.finish()
    return earth


def build_time(cfg: dict) -> TimeGrid:
    sec = Section(cfg.get("time"), "time")
    start = sec.non_negative("start")
    dt = sec.positive("dt")
    duration = sec.positive("duration")
    sec.get("pacing_window", int, 0, lambda v: v >= 0, ">= 0")
    sec.finish()
    dt_ns = int(round(dt * 1e9))
    return TimeGrid(int(round(start * 1e9)), dt_ns, int(round(duration / dt)) + 1)


def orbit_state(sec: Section, mu: float) -> np.ndarray:
    """ECI state at the epoch from Keplerian elements (angles in degrees, a in metres)."""
    a = sec.positive("a")
    e = sec.get("e", float, check=lambda v: 0.0 <= v < 1.0, expect="in [0, 1)")
    angles = [np.radians(sec.get(k, float)) for k in ("i_deg", "raan_deg", "argp_deg", "M_deg")]
    sec.finish()
    return kepler.kepler_to_cartesian(a, e, *angles, mu=mu)


def build_truth(cfg: dict) -> Truth:
    """Integrate the scenario's truth and sample it on the step grid."""
    earth = build_earth(cfg)
    grid = build_time(cfg)
    sec = Section(cfg.get("truth"), "truth")
    model = sec.choice("model", TRUTH_MODELS)
    x0 = orbit_state(sec.section("orbit", default_empty=False), earth.mu)
    sec.finish()
    j2 = earth.j2 if model == "cowell_j2" else 0.0
    times = np.concatenate([[0.0], grid.times()]) if grid.start_ns > 0 else grid.times()
    states = cowell.propagate(x0, times, mu=earth.mu, j2=j2, re=earth.re)
    if grid.start_ns > 0:
        states = states[1:]
    return Truth(grid, states, ORBIT_LABELS, "eci")
