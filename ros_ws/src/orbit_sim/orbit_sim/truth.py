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

from bench_engine import plugins
from bench_engine.config import ScenarioError
from bench_engine.labels import ORBIT
from bench_engine.scenario import scenario_seed
from bench_engine.settings import POSITIVE, Builder, Check, SectionReader, Settings, read, setting, variant
from bench_engine.timegrid import TimeGrid, build_time
from orbit_sim import cowell, frames, gravity, hill, kepler, relative
from orbit_sim.constants import J2_EARTH, MU_EARTH, OMEGA_EARTH, R_EARTH


@dataclass(frozen=True, kw_only=True)
class EarthSettings(Settings):
    """The scenario's ``earth`` section: the Earth model shared by truth, sensors and filters (they must agree
    on ECI <-> ECEF)."""

    mu: float = setting(MU_EARTH, unit="m^3/s^2", doc="gravitational parameter GM", check=POSITIVE)
    j2: float = setting(J2_EARTH, doc="second zonal harmonic (oblateness), unnormalised")
    re: float = setting(R_EARTH, unit="m", doc="equatorial radius", check=POSITIVE)
    rotation_rate: float = setting(OMEGA_EARTH, unit="rad/s", doc="rotation rate of ECEF about ECI's z axis")
    theta0_deg: float | None = setting(
        None,
        unit="deg",
        doc="Earth rotation angle (ECI x to ECEF x) at t = 0, "
        "without a calendar epoch (with time.epoch: the "
        "Greenwich mean sidereal time of the epoch)",
        default_text="0, or the sidereal time of time.epoch",
    )
    ut1_minus_utc_s: float | None = setting(
        None,
        unit="s",
        doc="UT1 - UTC at the epoch (with time.epoch only)",
        check=Check(lambda v: abs(v) < 1.0, "in (-1, 1) s (IERS keeps |UT1 - UTC| < 0.9 s)"),
        default_text="0",
    )


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
    """The Earth of the scenario's ``earth`` section (:class:`EarthSettings`). The Earth rotation angle at t = 0 is
    ``theta0_deg`` or, when the scenario has a calendar epoch (``time.epoch``), the Greenwich mean sidereal time of
    the epoch (frames.gmst82, of UT1 = UTC + ``ut1_minus_utc_s``, default 0; |UT1 - UTC| < 0.9 s): ``eci`` is then
    TEME and ECEF PEF (orbit_sim.frames). Giving both is an error: they would disagree."""
    sec = read(EarthSettings, cfg.get("earth"), "earth")
    epoch = build_time(cfg).epoch if isinstance(cfg.get("time"), dict) and "epoch" in cfg["time"] else None
    if epoch is None:
        if sec.ut1_minus_utc_s is not None:
            raise ScenarioError("'earth.ut1_minus_utc_s' needs a calendar epoch, 'time.epoch'")
        theta0 = np.radians(sec.theta0_deg or 0.0)
    elif sec.theta0_deg is not None:
        raise ScenarioError(
            "'earth.theta0_deg' and 'time.epoch' both fix the Earth's orientation at t = 0: with an "
            "epoch, theta0 is the sidereal time of the epoch; remove theta0_deg (or set it to null)"
        )
    else:
        dut1 = sec.ut1_minus_utc_s or 0.0
        theta0 = frames.gmst82(*frames.julian_date(epoch + datetime.timedelta(seconds=dut1)))
    return Earth(mu=sec.mu, j2=sec.j2, re=sec.re, rotation_rate=sec.rotation_rate, theta0=float(theta0))


EARTH = SectionReader("earth", EarthSettings, "the Earth model every truth, sensor and filter shares", build_earth)


A_RANGE_M = (1.0e6, 1.0e10)
"""Semi-major axes the bench accepts [m]: from inside the Earth (relative-motion studies only need the mean
motion) to beyond the Moon; outside, a typo is likelier than intent."""


@dataclass(frozen=True, kw_only=True)
class OrbitElements(Settings):
    """One spacecraft's Keplerian elements at the epoch: ``a`` or ``period_s`` (exactly one), the rest default 0."""

    a: float | None = setting(None, unit="m", doc="semi-major axis (exactly one of a and period_s)", check=POSITIVE)
    period_s: float | None = setting(
        None,
        unit="s",
        doc="orbital period, converted to a with Kepler's third law (exactly one of a and period_s)",
        check=POSITIVE,
    )
    e: float = setting(0.0, doc="eccentricity", check=Check(lambda v: 0.0 <= v < 1.0, "in [0, 1)"))
    i_deg: float = setting(0.0, unit="deg", doc="inclination")
    raan_deg: float = setting(0.0, unit="deg", doc="right ascension of the ascending node")
    argp_deg: float = setting(0.0, unit="deg", doc="argument of perigee")
    M_deg: float = setting(0.0, unit="deg", doc="mean anomaly at the epoch")

    def validate(self, path: str) -> None:
        if (self.a is None) == (self.period_s is None):
            raise ScenarioError(f"'{path}' needs exactly one of 'a' (m) or 'period_s' (s)")

    def semi_major_axis(self, mu: float) -> float:
        """``a`` [m], or ``period_s`` converted with Kepler's third law, in A_RANGE_M."""
        a = self.a if self.a is not None else float((mu * (self.period_s / (2.0 * np.pi)) ** 2) ** (1.0 / 3.0))
        if not A_RANGE_M[0] <= a <= A_RANGE_M[1]:
            key = self.where("a" if self.a is not None else "period_s")
            raise ScenarioError(
                f"'{key}' gives a semi-major axis of {a:.4g} m; it must be between "
                f"{A_RANGE_M[0]:g} and {A_RANGE_M[1]:g} m"
            )
        return a

    def state(self, mu: float) -> np.ndarray:
        """ECI state at the epoch."""
        angles = np.radians([self.i_deg, self.raan_deg, self.argp_deg, self.M_deg])
        return kepler.kepler_to_cartesian(self.semi_major_axis(mu), self.e, *angles, mu=mu)


@dataclass(frozen=True, kw_only=True)
class SingleOrbit(Settings):
    """``cowell_j2`` / ``cowell_twobody``: one spacecraft in ECI."""

    orbit: OrbitElements = setting(doc="the spacecraft's orbit")


@dataclass(frozen=True, kw_only=True)
class ProjectedCircularOrbit(Settings):
    """A deputy on a projected circular orbit about the chief, bounded under CW."""

    size: float = setting(unit="m", doc="diameter of the circle in the along-track/cross-track plane", check=POSITIVE)
    phase_deg: float = setting(0.0, unit="deg", doc="phase of the deputy on it at the epoch")


@dataclass(frozen=True, kw_only=True)
class Deputy(Settings):
    """The deputy's initial state relative to the chief: ``pco``, or ``position`` (and ``velocity``) in the axes
    of ``convention``."""

    pco: ProjectedCircularOrbit | None = setting(None, doc="a projected circular orbit (instead of position)")
    position: list[float] | None = setting(None, unit="m", doc="relative position, LVLH (instead of pco)")
    velocity: list[float] = setting([0.0, 0.0, 0.0], unit="m/s", doc="relative velocity as seen in LVLH")
    convention: str = setting(
        "radial_along_normal",
        choices=relative.CONVENTIONS,
        doc="the axes of position and velocity: radial_along_normal (x radial, y along-track, "
        "z orbit normal) or along_radial",
    )
    drift_free: bool = setting(
        False,
        doc="correct the deputy's along-track velocity so that its mean motion "
        "equals the chief's (no secular drift; two-body or J2 truths)",
    )

    def validate(self, path: str) -> None:
        if (self.pco is None) == (self.position is None):
            raise ScenarioError(f"'{path}' needs exactly one of 'pco' or 'position'")
        if self.position is not None and (len(self.position) != 3 or len(self.velocity) != 3):
            raise ScenarioError(f"'{path}.position' and '.velocity' must have 3 components each")

    def state(self, n: float) -> np.ndarray:
        """Initial relative state, internal LVLH axes. A projected circular orbit of diameter ``size``:
        x = size/4 sin, y = size/2 cos, z = size/2 sin of n t + phase."""
        if self.pco is not None:
            rho, phase = self.pco.size / 2.0, np.radians(self.pco.phase_deg)
            s, c = np.sin(phase), np.cos(phase)
            return np.array([rho / 2 * s, rho * c, rho * s, rho / 2 * n * c, -2 * rho / 2 * n * s, rho * n * c])
        return relative.from_convention(np.array(self.position + self.velocity, dtype=float), self.convention)


@dataclass(frozen=True, kw_only=True)
class Formation(Settings):
    """``formation_j2`` / ``formation_twobody`` / ``hill_cw``: a deputy relative to a chief, in the chief's LVLH
    frame."""

    chief: OrbitElements = setting(doc="the chief's orbit")
    deputy: Deputy = setting(doc="the deputy's initial state relative to the chief")


@dataclass(frozen=True)
class TruthModel(Builder):
    """A registered truth model (``tracking_bench.truth_models``): its keys of the ``truth`` section besides
    ``model`` (``settings``), ``build(settings, model name, earth, grid, seed) -> Truth`` (a ``module:function``)
    and the labels and frame of the state it publishes. ``seeded``: it draws from the run's seed."""

    labels: tuple[str, ...] = ()
    frame: str = ""
    seeded: bool = False


@dataclass(frozen=True, kw_only=True)
class TruthSection(Settings):
    """The scenario's ``truth`` section: a registered model and its keys."""

    model: str = setting(
        doc="a registered truth model (tracking_bench.truth_models)", choices=lambda: plugins.names("truth_models")
    )
    options: Settings = variant(
        "model", lambda: plugins.names("truth_models"), lambda name: plugins.load("truth_models", name).settings
    )


def read_truth(cfg: dict) -> TruthSection:
    """The scenario's ``truth`` section, read (nothing integrated: :func:`build_truth`)."""
    return read(TruthSection, cfg.get("truth"), "truth")


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
    earth, truth = build_earth(cfg), read_truth(cfg)
    if not isinstance(truth.options, Formation):
        raise ScenarioError("relative-motion models need the chief's orbit in 'truth.chief'")
    chief = truth.options.chief
    a = chief.semi_major_axis(earth.mu)
    if mean_radius:
        j2 = earth.j2 if truth.model == "formation_j2" else 0.0
        times = np.linspace(0.0, 2.0 * np.pi * np.sqrt(a**3 / earth.mu), 721)
        radii = np.linalg.norm(cowell.propagate(chief.state(earth.mu), times, earth.mu, j2, earth.re)[:, :3], axis=1)
        a = float(np.mean(radii[:-1]))
    return ReferenceOrbit(a, np.radians(chief.i_deg), float(np.sqrt(earth.mu / a**3)))


def _sampled(states: np.ndarray, grid: TimeGrid) -> np.ndarray:
    return states[1:] if grid.start_ns > 0 else states


def _times(grid: TimeGrid) -> np.ndarray:
    """The epoch (t = 0) and the grid's times: integrations start at the epoch."""
    return np.concatenate([[0.0], grid.times()]) if grid.start_ns > 0 else grid.times()


def formation_truth(sec: Formation, model: str, earth: Earth, grid: TimeGrid, seed: int = 0) -> Truth:
    """Relative LVLH states on the grid (nonlinear two-body (+ J2) of both spacecraft, or exact CW)."""
    chief0 = sec.chief.state(earth.mu)
    n = float(np.sqrt(earth.mu / np.linalg.norm(chief0[:3]) ** 3))
    rel0 = sec.deputy.state(n)
    times = _times(grid)
    if model == "hill_cw":
        states = hill.cw_propagate(rel0, times, n)
    else:
        j2 = earth.j2 if model == "formation_j2" else 0.0
        if sec.deputy.drift_free:
            rel0 = relative.drift_free(chief0, rel0, earth.mu, j2, earth.re)
        a0 = gravity.acceleration(chief0[:3], earth.mu, j2, earth.re)
        deputy0 = relative.lvlh_to_eci(chief0, rel0, a0)
        chief = cowell.propagate(chief0, times, mu=earth.mu, j2=j2, re=earth.re)
        deputy = cowell.propagate(deputy0, times, mu=earth.mu, j2=j2, re=earth.re)
        accel = gravity.acceleration(chief[:, :3], earth.mu, j2, earth.re)
        states = relative.eci_to_lvlh(chief, deputy, accel)
    return Truth(grid, _sampled(states, grid), ORBIT, "lvlh")


def single_orbit_truth(sec: SingleOrbit, model: str, earth: Earth, grid: TimeGrid, seed: int = 0) -> Truth:
    """One spacecraft in ECI from ``truth.orbit`` (Keplerian elements), two-body (+ J2 for ``cowell_j2``)."""
    j2 = earth.j2 if model == "cowell_j2" else 0.0
    states = cowell.propagate(sec.orbit.state(earth.mu), _times(grid), mu=earth.mu, j2=j2, re=earth.re)
    return Truth(grid, _sampled(states, grid), ORBIT, "eci")


@dataclass(frozen=True, kw_only=True)
class Sgp4(Settings):
    """``sgp4``: a real satellite from its two-line element set, propagated by SGP4 in TEME (orbit_sim.tle); needs
    ``time.epoch``."""

    tle: list[str] | None = setting(
        None, doc="the element set's two lines (or a title line and the two; exactly one of tle and tle_file)"
    )
    tle_file: str | None = setting(None, doc="a file holding one element set (exactly one of tle and tle_file)")

    def validate(self, path: str) -> None:
        if (self.tle is None) == (self.tle_file is None):
            raise ScenarioError(f"'{path}' needs exactly one of 'tle' (the element set's lines) or 'tle_file'")


SINGLE_ORBIT = TruthModel(SingleOrbit, "orbit_sim.truth:single_orbit_truth", ORBIT, "eci")
FORMATION = TruthModel(Formation, "orbit_sim.truth:formation_truth", ORBIT, "lvlh")
SGP4 = TruthModel(Sgp4, "orbit_sim.tle:tle_truth", ORBIT, "eci")
"""Registered here, with its settings, so the graph reads them without loading the SGP4 propagator."""


def build_truth(cfg: dict) -> Truth:
    """Integrate the scenario's truth and sample it on the step grid (cached per truth configuration).

    ``truth.model`` names a registered :class:`TruthModel` (entry-point group ``tracking_bench.truth_models``).
    A model with random parts (``seeded``) draws from the run's seed, so Monte Carlo runs draw them anew."""
    fields = {k: cfg.get(k) for k in ("earth", "time", "truth")}
    model = read_truth(cfg).model
    fields["seed"] = scenario_seed(cfg) if plugins.load("truth_models", model).seeded else 0
    return _build_truth(json.dumps(fields, sort_keys=True, default=str))


TRUTH = SectionReader(
    "truth", TruthSection, "the ground truth of the run: a registered model and its keys", build_truth
)


@lru_cache(maxsize=4)
def _build_truth(key: str) -> Truth:
    cfg = json.loads(key)
    truth = read_truth(cfg)
    model = plugins.load("truth_models", truth.model)
    states = model(truth.options, truth.model, build_earth(cfg), build_time(cfg), cfg["seed"])
    states.states.setflags(write=False)
    return states
