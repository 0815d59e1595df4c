"""Ground truth of a run, built from the scenario's ``earth``, ``time`` and ``truth`` sections.

The whole trajectory is integrated up front with Cowell's method (``cowell.propagate``, solve_ivp at tight
tolerances) and sampled on the run's step grid; the truth source then only publishes rows.

Models (``truth.model``, registered in the entry-point group ``tracking_bench.truth_models``):
- ``cowell_j2`` / ``cowell_twobody``: one spacecraft, ECI state [x y z vx vy vz] (frame "eci").
- ``formation_j2`` / ``formation_twobody``: chief and deputy each propagated in ECI; the published state is
  the deputy relative to the chief in the chief's LVLH frame (x radial, y along-track, z orbit normal),
  velocity as seen in the rotating frame (frame "lvlh").
- ``hill_cw``: the relative state from the exact solution of the Hill/Clohessy-Wiltshire equations.
"""
from __future__ import annotations

import datetime
import json
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from orbit_sim import cowell, frames, gravity, hill, kepler, relative
from bench_engine import plugins
from bench_engine.config import ScenarioError, Section
from bench_engine.labels import ORBIT
from bench_engine.scenario import scenario_seed
from bench_engine.timegrid import TimeGrid, build_time
from orbit_sim.constants import J2_EARTH, MU_EARTH, OMEGA_EARTH, R_EARTH



@dataclass(frozen=True)
class Earth:
    """Earth model shared by truth, sensors and filters (they must agree on ECI <-> ECEF)."""

    mu: float = MU_EARTH
    j2: float = J2_EARTH
    re: float = R_EARTH
    rotation_rate: float = OMEGA_EARTH
    theta0: float = 0.0  # Earth rotation angle at the epoch [rad]


@dataclass
class Truth:
    grid: TimeGrid
    states: np.ndarray  # (steps, n)
    labels: tuple[str, ...]
    frame: str


def build_earth(cfg: dict) -> Earth:
    """The ``earth`` section. The Earth rotation angle at t = 0 is ``theta0_deg`` or, when the scenario has a
    calendar epoch (``time.epoch``), the Greenwich mean sidereal time of the epoch (frames.gmst82, of UT1 = UTC +
    ``ut1_minus_utc_s``, default 0; |UT1 - UTC| < 0.9 s): ``eci`` is then TEME and ECEF PEF (orbit_sim.frames).
    Giving both is an error: they would disagree."""
    sec = Section(cfg.get("earth"), "earth")
    epoch = build_time(cfg).epoch if isinstance(cfg.get("time"), dict) and "epoch" in cfg["time"] else None
    dut1 = sec.get("ut1_minus_utc_s", float, 0.0, lambda v: abs(v) < 1.0, "in (-1, 1) s (IERS keeps |UT1 - UTC| < 0.9 s)")
    if epoch is None:
        if "ut1_minus_utc_s" in sec.data:
            raise ScenarioError("'earth.ut1_minus_utc_s' needs a calendar epoch, 'time.epoch'")
        theta0 = np.radians(sec.get("theta0_deg", float, 0.0))
    elif sec.get("theta0_deg", float, None) is not None:
        raise ScenarioError("'earth.theta0_deg' and 'time.epoch' both fix the Earth's orientation at t = 0: with an "
                            "epoch, theta0 is the sidereal time of the epoch; remove theta0_deg (or set it to null)")
    else:
        theta0 = frames.gmst82(*frames.julian_date(epoch + datetime.timedelta(seconds=dut1)))
    earth = Earth(mu=sec.positive("mu", MU_EARTH), j2=sec.get("j2", float, J2_EARTH),
                  re=sec.positive("re", R_EARTH), rotation_rate=sec.get("rotation_rate", float, OMEGA_EARTH),
                  theta0=float(theta0))
    sec.finish()
    return earth


A_RANGE_M = (1.0e6, 1.0e10)
"""Semi-major axes the bench accepts [m]: from inside the Earth (relative-motion studies only need the mean
motion) to beyond the Moon; outside, a typo is likelier than intent."""


def semi_major_axis(sec: Section, mu: float) -> float:
    """``a`` [m], or ``period_s`` converted with Kepler's third law (exactly one of them), in A_RANGE_M."""
    if ("a" in sec.data) == ("period_s" in sec.data):
        raise ScenarioError(f"'{sec.path}' needs exactly one of 'a' (m) or 'period_s' (s)")
    if "a" in sec.data:
        sec.mark("period_s")
        a, key = sec.positive("a"), "a"
    else:
        sec.mark("a")
        period, key = sec.positive("period_s"), "period_s"
        if not all(2.0 * np.pi * np.sqrt(lim**3 / mu) * f <= period * f for lim, f in zip(A_RANGE_M, (1, -1))):
            raise ScenarioError(f"'{sec.path}.period_s' is {period:g} s; it must give a semi-major axis between "
                                f"{A_RANGE_M[0]:g} and {A_RANGE_M[1]:g} m")
        a = float((mu * (period / (2.0 * np.pi)) ** 2) ** (1.0 / 3.0))
    if not A_RANGE_M[0] <= a <= A_RANGE_M[1]:
        raise ScenarioError(f"'{sec.path}.{key}' gives a semi-major axis of {a:.4g} m; it must be between "
                            f"{A_RANGE_M[0]:g} and {A_RANGE_M[1]:g} m")
    return a


def orbit_state(sec: Section, mu: float) -> np.ndarray:
    """ECI state at the epoch from Keplerian elements (angles in degrees; ``a`` in metres or ``period_s``)."""
    a = semi_major_axis(sec, mu)
    e = sec.get("e", float, 0.0, lambda v: 0.0 <= v < 1.0, "in [0, 1)")
    angles = [np.radians(sec.get(k, float, 0.0)) for k in ("i_deg", "raan_deg", "argp_deg", "M_deg")]
    sec.finish()
    return kepler.kepler_to_cartesian(a, e, *angles, mu=mu)


@dataclass(frozen=True)
class ReferenceOrbit:
    """The chief's orbit as the linear relative-motion models see it."""

    a: float  # semi-major axis [m]
    inclination: float  # [rad]
    n: float  # mean motion [rad/s]


def reference_orbit(cfg: dict, mean_radius: bool = False) -> ReferenceOrbit:
    """Radius, inclination and mean motion of ``truth.chief`` as the linear models see it (formations).

    Default: the stated semi-major axis. With ``mean_radius`` the radius is the chief's orbit-averaged |r|
    under the truth's gravity (two-body + J2 for ``formation_j2``): the reference radius the
    Schweighart-Sedwick model is derived for, which differs from the osculating a by kilometres under J2.
    """
    earth = build_earth(cfg)
    chief = (cfg.get("truth") or {}).get("chief")
    if not isinstance(chief, dict):
        raise ScenarioError("relative-motion models need the chief's orbit in 'truth.chief'")
    a = semi_major_axis(Section(chief, "truth.chief"), earth.mu)
    if mean_radius:
        x0 = orbit_state(Section(chief, "truth.chief"), earth.mu)
        j2 = earth.j2 if (cfg.get("truth") or {}).get("model") == "formation_j2" else 0.0
        times = np.linspace(0.0, 2.0 * np.pi * np.sqrt(a**3 / earth.mu), 721)
        radii = np.linalg.norm(cowell.propagate(x0, times, earth.mu, j2, earth.re)[:, :3], axis=1)
        a = float(np.mean(radii[:-1]))
    inclination = np.radians(Section(chief, "truth.chief").get("i_deg", float, 0.0))
    return ReferenceOrbit(a, inclination, float(np.sqrt(earth.mu / a**3)))


def _relative_initial_state(sec: Section, n: float) -> np.ndarray:
    """Initial relative state, internal LVLH axes, from ``truth.deputy``.

    Either ``position``/``velocity`` given in the axes of ``convention`` ("radial_along_normal" = internal,
    "along_radial" = paper 001), or ``pco: {size, phase_deg}``: a projected circular orbit of diameter
    ``size`` in the along-track/cross-track plane, bounded under CW (x = size/4 sin, y = size/2 cos,
    z = size/2 sin of n t + phase).
    """
    if "pco" in sec.data:
        pco = sec.section("pco")
        rho, phase = pco.positive("size") / 2.0, np.radians(pco.get("phase_deg", float, 0.0))
        pco.finish()
        sec.mark("position", "velocity", "convention")
        s, c = np.sin(phase), np.cos(phase)
        return np.array([rho / 2 * s, rho * c, rho * s, rho / 2 * n * c, -2 * rho / 2 * n * s, rho * n * c])
    convention = sec.choice("convention", relative.CONVENTIONS, "radial_along_normal")
    vec = sec.get("position", list) + sec.get("velocity", list, [0.0, 0.0, 0.0])
    if len(vec) != 6:
        raise ScenarioError(f"'{sec.path}.position' and '.velocity' must have 3 components each")
    return relative.from_convention(np.array(vec, dtype=float), convention)


def formation_truth(sec: Section, model: str, earth: Earth, grid: TimeGrid) -> Truth:
    """Relative LVLH states on the grid (nonlinear two-body (+ J2) of both spacecraft, or exact CW)."""
    chief0 = orbit_state(sec.section("chief", default_empty=False), earth.mu)
    n = float(np.sqrt(earth.mu / np.linalg.norm(chief0[:3]) ** 3))
    dep = sec.section("deputy", default_empty=False)
    correct = dep.get("drift_free", bool, False)
    rel0 = _relative_initial_state(dep, n)
    dep.finish()
    times = np.concatenate([[0.0], grid.times()]) if grid.start_ns > 0 else grid.times()
    if model == "hill_cw":
        states = hill.cw_propagate(rel0, times, n)
    else:
        j2 = earth.j2 if model == "formation_j2" else 0.0
        if correct:
            rel0 = relative.drift_free(chief0, rel0, earth.mu, j2, earth.re)
        a0 = gravity.acceleration(chief0[:3], earth.mu, j2, earth.re)
        deputy0 = relative.lvlh_to_eci(chief0, rel0, a0)
        chief = cowell.propagate(chief0, times, mu=earth.mu, j2=j2, re=earth.re)
        deputy = cowell.propagate(deputy0, times, mu=earth.mu, j2=j2, re=earth.re)
        accel = gravity.acceleration(chief[:, :3], earth.mu, j2, earth.re)
        states = relative.eci_to_lvlh(chief, deputy, accel)
    return Truth(grid, states[1:] if grid.start_ns > 0 else states, ORBIT, "lvlh")


def single_orbit_truth(sec: Section, model: str, earth: Earth, grid: TimeGrid) -> Truth:
    """One spacecraft in ECI from ``truth.orbit`` (Keplerian elements), two-body (+ J2 for ``cowell_j2``)."""
    x0 = orbit_state(sec.section("orbit", default_empty=False), earth.mu)
    j2 = earth.j2 if model == "cowell_j2" else 0.0
    times = np.concatenate([[0.0], grid.times()]) if grid.start_ns > 0 else grid.times()
    states = cowell.propagate(x0, times, mu=earth.mu, j2=j2, re=earth.re)
    return Truth(grid, states[1:] if grid.start_ns > 0 else states, ORBIT, "eci")


def build_truth(cfg: dict) -> Truth:
    """Integrate the scenario's truth and sample it on the step grid (cached per truth configuration).

    ``truth.model`` names a registered truth model (entry-point group ``tracking_bench.truth_models``): a
    function (section, model name, earth, grid) -> Truth. A model with random parts (attribute ``seeded``)
    also receives ``seed=`` the run's seed, so Monte Carlo runs draw them anew."""
    fields = {k: cfg.get(k) for k in ("earth", "time", "truth")}
    if getattr(_model_function(cfg), "seeded", False):
        fields["seed"] = scenario_seed(cfg)
    return _build_truth(json.dumps(fields, sort_keys=True, default=str))


def _model_function(cfg: dict):
    """The registered function of ``truth.model``, or None when the name is unknown (reported by Section)."""
    truth = cfg.get("truth")
    model = truth.get("model") if isinstance(truth, dict) else None
    return plugins.load("truth_models", model) if model in plugins.names("truth_models") else None


@lru_cache(maxsize=4)
def _build_truth(key: str) -> Truth:
    cfg = json.loads(key)
    earth = build_earth(cfg)
    grid = build_time(cfg)
    sec = Section(cfg.get("truth"), "truth")
    model = sec.choice("model", plugins.names("truth_models"))
    seed = {"seed": cfg["seed"]} if "seed" in cfg else {}
    truth = plugins.load("truth_models", model)(sec, model, earth, grid, **seed)
    sec.finish()
    truth.states.setflags(write=False)
    return truth
