"""Scenario -> filter objects: dynamics model, filter, initialiser and the sensors a filter consumes.

A filter node's behaviour comes entirely from its settings (tracker_filters.filter_settings: ``filter_defaults``
merged with ``filters.NAME``, declared and read there); the registered dynamics models and initialisers
(filter_settings' Builders) build here.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from dataclasses import dataclass, fields

import numpy as np

from bench_engine import plugins
from bench_engine.config import ScenarioError
from bench_engine.scenario import scenario_seed
from bench_models.given_noise import GivenProcessNoise
from bench_models.models import DynamicsModel, ScanPositionModel
from bench_models.orbit_dynamics import OrbitJ2Dynamics
from bench_models.relative_dynamics import CWBiasDynamics, CWDynamics, SchweighartSedwickDynamics
from bench_models.white_jerk import WhiteJerkDynamics
from orbit_sim import relative
from orbit_sim.truth import build_earth, build_truth, reference_orbit
from radar_sensor.sensor import Sensor, build_sensor
from radar_sensor.sensor_types import sensor_names
from tracker_filters import registry
from tracker_filters.derived import DerivedSource, derived_source, read_derived
from tracker_filters.filter_base import Filter
from tracker_filters.filter_settings import (
    Cw,
    CwBias,
    DynamicsSettings,
    FirstScan,
    Given,
    InitSettings,
    OrbitJ2,
    PositionFix,
    RelativeMotion,
    Ss,
    TruthScaled,
    WhiteJerk,
    filter_settings,
)
from tracker_filters.initialisation import initial_state_from_scan

Initialiser = Callable[[np.ndarray, np.ndarray, Sensor, float], tuple[np.ndarray, np.ndarray]]
"""(z, R, sensor, t) -> (x0, P0). An initialiser that needs more of a measurement model than the
MeasurementModel protocol states says so in an attribute ``requires`` (a runtime-checkable Protocol): every
measurement the filter consumes must satisfy it, checked when the filter is built (validation)."""


@dataclass
class FilterStack:
    """Everything a filter node needs."""

    name: str
    filter: Filter
    sensors: dict[str, Sensor]
    initialise: Initialiser
    reinit_after_gated: int = 3
    """Consecutive gated measurements after which the filter has lost lock and restarts from the next one."""


def orbit_j2(sec: OrbitJ2, cfg: dict) -> DynamicsModel:
    earth = build_earth(cfg)
    return OrbitJ2Dynamics(sec.sigma_accel, mu=earth.mu, j2=earth.j2, re=earth.re)


def _reference(sec: RelativeMotion, cfg: dict):
    """The chief's reference orbit: ``reference: stated`` (the scenario's a) or ``mean`` (orbit-averaged)."""
    return reference_orbit(cfg, sec.reference == "mean")


def cw(sec: Cw, cfg: dict) -> DynamicsModel:
    return CWDynamics(_reference(sec, cfg).n, sec.sigma_accel, sec.discretisation)


def cw_bias(sec: CwBias, cfg: dict) -> DynamicsModel:
    return CWBiasDynamics(_reference(sec, cfg).n, sec.sigma_accel, sec.sigma_bias)


def ss(sec: Ss, cfg: dict) -> DynamicsModel:
    ref, earth = _reference(sec, cfg), build_earth(cfg)
    return SchweighartSedwickDynamics(ref.a, ref.inclination, sec.sigma_accel, earth.mu, earth.j2, earth.re)


def white_jerk(sec: WhiteJerk, cfg: dict) -> DynamicsModel:
    """Paper 002's kinematic model: ``q`` [m^2/s^5] white-jerk density, ``labels`` (positions, velocities,
    accelerations), ``frame``."""
    return WhiteJerkDynamics(sec.q, sec.labels, sec.frame)


def build_dynamics(sec: DynamicsSettings, cfg: dict) -> DynamicsModel:
    """The dynamics model of a filter's ``dynamics`` (with its given process noise, ``q_diagonal``)."""
    dynamics = plugins.load("dynamics", sec.model)(sec.options, cfg)
    q = sec.q_diagonal
    if q is None:
        return dynamics
    if len(q) != len(dynamics.labels):
        raise ScenarioError(f"'{sec.where('q_diagonal')}' must hold {len(dynamics.labels)} values >= 0, got {q}")
    M = np.kron(np.eye(len(q) // 3), relative.convention_matrix(sec.q_convention).T)  # convention -> internal
    return GivenProcessNoise(dynamics, M @ np.diag(np.asarray(q, dtype=float)) @ M.T, sec.q_reference_dt)


def first_scan(sec: FirstScan, cfg: dict, dynamics: DynamicsModel) -> Initialiser:
    velocity_sigma = sec.velocity_sigma

    def initialise(z: np.ndarray, R: np.ndarray, sensor: Sensor, t: float) -> tuple[np.ndarray, np.ndarray]:
        return initial_state_from_scan(z, R, sensor.model, t, velocity_sigma)

    initialise.requires = ScanPositionModel
    return initialise


def _padded(values: np.ndarray, extra: list[float] | None, key: str, n: int) -> np.ndarray:
    """6 relative-state values, extended with ``extra`` (e.g. the bias; zeros if None) for longer states
    (CW+bias: 9)."""
    if n == len(values):
        return values
    extra = [0.0] * (n - len(values)) if extra is None else extra
    if len(values) + len(extra) != n:
        raise ScenarioError(f"'{key}' must have {n - len(values)} values for a {n}-state filter")
    return np.concatenate([values, np.asarray(extra, dtype=float)])


def given(sec: Given, cfg: dict, dynamics: DynamicsModel) -> Initialiser:
    """Initial estimate and standard deviations stated by the paper, in ``convention`` axes."""
    n = len(dynamics.labels)
    mean, sigma = np.asarray(sec.mean, float), np.asarray(sec.sigma, float)
    x0 = _padded(relative.from_convention(mean, sec.convention), sec.bias_mean, sec.where("bias_mean"), n)
    s0 = _padded(np.abs(relative.from_convention(sigma, sec.convention)), sec.bias_sigma, sec.where("bias_sigma"), n)
    return lambda z, R, sensor, t: (x0.copy(), np.diag(s0**2))


def truth_scaled(sec: TruthScaled, cfg: dict, dynamics: DynamicsModel) -> Initialiser:
    """Paper 004: initial estimate = true initial state with a relative error (2 %), diagonal P0."""
    n = len(dynamics.labels)
    x_true = build_truth(cfg).states[0]
    x0 = _padded(x_true * (1.0 + sec.error_fraction), sec.bias_mean, sec.where("bias_mean"), n)
    s0 = np.array([sec.sigma_position] * 3 + [sec.sigma_velocity] * 3 + [sec.sigma_bias] * (n - 6))
    return lambda z, R, sensor, t: (x0.copy(), np.diag(s0**2))


def position_fix(sec: PositionFix, cfg: dict, dynamics: DynamicsModel) -> Initialiser:
    """From the first measurement of components of a kinematic state ordered in three equal blocks
    (positions, velocities, accelerations; bench_models.white_jerk): the measured components take z and R,
    the others zero mean with ``sigma_velocity`` or ``sigma_acceleration`` [SI]."""
    n = len(dynamics.labels)
    if n % 3:
        raise ScenarioError(
            f"'{sec.where()}': position_fix needs a state of positions, velocities and "
            f"accelerations in three equal blocks, got {list(dynamics.labels)}"
        )
    prior = np.repeat([np.inf, sec.sigma_velocity, sec.sigma_acceleration], n // 3)

    def initialise(z: np.ndarray, R: np.ndarray, sensor: Sensor, t: float) -> tuple[np.ndarray, np.ndarray]:
        H = sensor.model.jacobian(np.zeros(n), t)
        measured = [int(np.flatnonzero(row)[0]) for row in H]
        if not np.all(np.isfinite(np.delete(prior, measured))):
            raise ValueError(f"{sensor.name}'s first measurement leaves state positions unknown")
        x0, P0 = np.zeros(n), np.diag(np.where(np.isfinite(prior), prior, 0.0) ** 2)
        x0[measured] = z
        P0[np.ix_(measured, measured)] = R
        return x0, P0

    return initialise


def build_initialiser(sec: InitSettings, cfg: dict, dynamics: DynamicsModel) -> Initialiser:
    return plugins.load("initialisers", sec.method)(sec.options, cfg, dynamics)


def build_filter_stack(cfg: dict, name: str) -> FilterStack:
    """Build filter node ``name``; every bad key or value raises ScenarioError naming it."""
    sec = filter_settings(cfg, name)
    dynamics = build_dynamics(sec.dynamics, cfg)
    init = build_initialiser(sec.init, cfg, dynamics)
    params = {f.name: getattr(sec.params, f.name) for f in fields(sec.params)}
    if params.get("seed", 0) is None:
        # random filters (particle filters) draw from the run's seed, distinct per filter name
        params["seed"] = [scenario_seed(cfg), zlib.crc32(name.encode())]
    try:
        flt = registry.make_filter(sec.type, dynamics, **params)
    except (TypeError, ValueError) as err:
        raise ScenarioError(f"'filters.{name}.params': {err}") from err
    flt.name = name
    flt.gate_probability = sec.gate_probability
    sources = {s: measurement_source(cfg, s, dynamics.labels) for s in sec.sensors or sensor_names(cfg)}
    _check_initialiser(init, sources, f"filters.{name}.init")
    return FilterStack(name, flt, sources, init, sec.gate_reinit_after)


def _check_initialiser(init: Initialiser, sources: dict, path: str) -> None:
    """Every measurement the filter consumes offers what its initialiser ``requires`` (ScenarioError if not)."""
    requires = getattr(init, "requires", None)
    for name, source in sources.items():
        if requires is not None and not isinstance(source.model, requires):
            raise ScenarioError(
                f"'{path}' starts the filter from one measurement through the model's "
                f"{requires.__name__} methods, which measurement '{name}' "
                f"({type(source.model).__name__}) does not have; choose another init method "
                f"(e.g. given) or a sensor whose model has them"
            )


def measurement_source(cfg: dict, name: str, state_labels) -> Sensor | DerivedSource:
    """A sensor or a derived measurement a filter consumes, its model bound to the filter's state layout
    (models on named components, bench_models.labelled; ScenarioError when the state lacks them)."""
    source = derived_source(cfg, name) if name in read_derived(cfg) else build_sensor(cfg, name)
    try:
        source.bind(list(state_labels))
    except ValueError as err:
        raise ScenarioError(f"measurement '{name}' does not fit the filter's state: {err}") from None
    return source
