"""Scenario -> filter objects: dynamics model, filter, initialiser and the sensors a filter consumes.

A filter node's behaviour comes entirely from ``filter_defaults`` merged with ``filters.NAME``:

    type: ukf                 # a registered estimator (entry-point group tracking_bench.estimators)
    sensors: [radar]          # measurement topics it consumes
    dynamics: {model: orbit_j2, sigma_accel: 0.5}
    init: {method: first_scan, velocity_sigma: 8000.0}
    params: {alpha: 1.0}      # constructor parameters of the filter type
    gate_probability: 0.9999  # optional NIS gate: reject measurements beyond this chi-square quantile
    gate_reinit_after: 3      # that many consecutive gated measurements: lock lost, restart from the next one
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass
from typing import Callable

import numpy as np

from orbit_sim import relative
from bench_engine.config import ScenarioError, Section
from bench_engine.scenario import scenario_seed
from bench_engine import plugins
from orbit_sim.truth import build_earth, build_truth, reference_orbit
from radar_sensor.sensor import Sensor, build_sensor
from radar_sensor.sensor_types import sensor_names
from tracker_filters import registry
from tracker_filters.derived import DerivedSource, derived_source, read_derived
from tracker_filters.filter_base import Filter
from tracker_filters.filter_settings import filter_config
from bench_models.given_noise import GivenProcessNoise
from tracker_filters.initialisation import initial_state_from_scan
from bench_models.models import DynamicsModel, ScanPositionModel
from bench_models.orbit_dynamics import OrbitJ2Dynamics
from bench_models.relative_dynamics import CWBiasDynamics, CWDynamics, SchweighartSedwickDynamics
from bench_models.white_jerk import WhiteJerkDynamics

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


def orbit_j2(sec: Section, cfg: dict) -> DynamicsModel:
    earth = build_earth(cfg)
    return OrbitJ2Dynamics(sec.non_negative("sigma_accel"), mu=earth.mu, j2=earth.j2, re=earth.re)


def _sigma_accel(sec: Section) -> float | list[float]:
    """``sigma_accel`` [m/s^1.5, square root of the white-acceleration spectral density]: one value, or one
    per LVLH axis (internal axes: radial, along, normal)."""
    value = sec.get("sigma_accel", (float, list))
    values = np.atleast_1d(np.asarray(value, dtype=float))
    if values.shape not in ((1,), (3,)) or np.any(values < 0):
        raise ScenarioError(f"'{sec.path}.sigma_accel' must be >= 0, one value or three, got {value!r}")
    return value


def _reference(sec: Section, cfg: dict):
    """The chief's reference orbit: ``reference: stated`` (the scenario's a) or ``mean`` (orbit-averaged)."""
    return reference_orbit(cfg, sec.choice("reference", ("stated", "mean"), "stated") == "mean")


def cw(sec: Section, cfg: dict) -> DynamicsModel:
    return CWDynamics(_reference(sec, cfg).n, _sigma_accel(sec),
                      sec.choice("discretisation", ("exact", "euler"), "exact"))


def cw_bias(sec: Section, cfg: dict) -> DynamicsModel:
    return CWBiasDynamics(_reference(sec, cfg).n, _sigma_accel(sec), sec.non_negative("sigma_bias"))


def ss(sec: Section, cfg: dict) -> DynamicsModel:
    ref, earth = _reference(sec, cfg), build_earth(cfg)
    return SchweighartSedwickDynamics(ref.a, ref.inclination, _sigma_accel(sec), earth.mu, earth.j2, earth.re)


def white_jerk(sec: Section, cfg: dict) -> DynamicsModel:
    """Paper 002's kinematic model: ``q`` [m^2/s^5] white-jerk density, ``labels`` (positions, velocities,
    accelerations), ``frame``."""
    labels = sec.get("labels", list)
    if len(labels) != 9 or not all(isinstance(s, str) for s in labels) or len(set(labels)) != 9:
        raise ScenarioError(f"'{sec.path}.labels' must name 9 distinct components (3 positions, 3 velocities, "
                            f"3 accelerations), got {labels!r}")
    return WhiteJerkDynamics(sec.non_negative("q"), labels, sec.get("frame", str, "eci"))


def _given_q(sec: Section, dynamics: DynamicsModel) -> DynamicsModel:
    """Optional ``q_diagonal`` (per-step discrete Q at ``q_reference_dt``, in ``q_convention`` axes)."""
    q = sec.get("q_diagonal", list, None)
    convention = sec.choice("q_convention", relative.CONVENTIONS, "radial_along_normal")
    reference_dt = sec.positive("q_reference_dt", 1.0)
    if q is None:
        return dynamics
    if len(q) != len(dynamics.labels) or any(float(v) < 0 for v in q):
        raise ScenarioError(f"'{sec.path}.q_diagonal' must hold {len(dynamics.labels)} values >= 0, got {q}")
    M = np.kron(np.eye(len(q) // 3), relative.convention_matrix(convention).T)  # convention -> internal
    return GivenProcessNoise(dynamics, M @ np.diag(np.asarray(q, dtype=float)) @ M.T, reference_dt)


def build_dynamics(sec: Section, cfg: dict) -> DynamicsModel:
    model = sec.choice("model", plugins.names("dynamics"))
    dynamics = _given_q(sec, plugins.load("dynamics", model)(sec, cfg))
    sec.finish()
    return dynamics


def first_scan(sec: Section, cfg: dict, dynamics: DynamicsModel) -> Initialiser:
    velocity_sigma = sec.positive("velocity_sigma")

    def initialise(z: np.ndarray, R: np.ndarray, sensor: Sensor, t: float) -> tuple[np.ndarray, np.ndarray]:
        return initial_state_from_scan(z, R, sensor.model, t, velocity_sigma)
    initialise.requires = ScanPositionModel
    return initialise


def _padded(values: np.ndarray, sec: Section, key: str, n: int) -> np.ndarray:
    """6 relative-state values, extended with ``key`` (e.g. the bias) for longer states (CW+bias: 9)."""
    extra = sec.get(key, list, [0.0] * (n - len(values)))  # read even for 6 states: shared defaults
    if n == len(values):
        return values
    if len(values) + len(extra) != n:
        raise ScenarioError(f"'{sec.path}.{key}' must have {n - len(values)} values for a {n}-state filter")
    return np.concatenate([values, np.asarray(extra, dtype=float)])


def given(sec: Section, cfg: dict, dynamics: DynamicsModel) -> Initialiser:
    """Initial estimate and standard deviations stated by the paper, in ``convention`` axes."""
    n = len(dynamics.labels)
    convention = sec.choice("convention", relative.CONVENTIONS, "radial_along_normal")
    mean, sigma = np.asarray(sec.get("mean", list), float), np.asarray(sec.get("sigma", list), float)
    if mean.shape != (6,) or sigma.shape != (6,) or np.any(sigma <= 0):
        raise ScenarioError(f"'{sec.path}.mean' and '.sigma' must have 6 values (sigma > 0)")
    x0 = _padded(relative.from_convention(mean, convention), sec, "bias_mean", n)
    s0 = _padded(np.abs(relative.from_convention(sigma, convention)), sec, "bias_sigma", n)
    return lambda z, R, sensor, t: (x0.copy(), np.diag(s0**2))


def truth_scaled(sec: Section, cfg: dict, dynamics: DynamicsModel) -> Initialiser:
    """Paper 004: initial estimate = true initial state with a relative error (2 %), diagonal P0."""
    n = len(dynamics.labels)
    fraction = sec.get("error_fraction", float, check=lambda v: v >= 0, expect=">= 0")
    sp, sv = sec.positive("sigma_position"), sec.positive("sigma_velocity")
    sb = sec.positive("sigma_bias", 1e-6)  # CW+bias only
    x_true = build_truth(cfg).states[0]
    x0 = _padded(x_true * (1.0 + fraction), sec, "bias_mean", n)
    s0 = np.array([sp] * 3 + [sv] * 3 + [sb] * (n - 6))
    return lambda z, R, sensor, t: (x0.copy(), np.diag(s0**2))


def position_fix(sec: Section, cfg: dict, dynamics: DynamicsModel) -> Initialiser:
    """From the first measurement of components of a kinematic state ordered in three equal blocks
    (positions, velocities, accelerations; bench_models.white_jerk): the measured components take z and R,
    the others zero mean with ``sigma_velocity`` or ``sigma_acceleration`` [SI]."""
    sv, sa = sec.positive("sigma_velocity"), sec.positive("sigma_acceleration")
    n = len(dynamics.labels)
    if n % 3:
        raise ScenarioError(f"'{sec.path}': position_fix needs a state of positions, velocities and "
                            f"accelerations in three equal blocks, got {list(dynamics.labels)}")
    prior = np.repeat([np.inf, sv, sa], n // 3)

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


def build_initialiser(sec: Section, cfg: dict, dynamics: DynamicsModel) -> Initialiser:
    method = sec.choice("method", plugins.names("initialisers"))
    init = plugins.load("initialisers", method)(sec, cfg, dynamics)
    sec.finish()
    return init


def build_filter_stack(cfg: dict, name: str) -> FilterStack:
    """Build filter node ``name``; every bad key or value raises ScenarioError naming it."""
    sec = Section(filter_config(cfg, name), f"filters.{name}")
    kind = sec.choice("type", registry.filter_names())
    inputs = sec.get("sensors", list, sensor_names(cfg))
    dynamics = build_dynamics(sec.section("dynamics", default_empty=False), cfg)
    init = build_initialiser(sec.section("init", default_empty=False), cfg, dynamics)
    params = dict(sec.get("params", dict, {}))
    gate = sec.get("gate_probability", float, 0.0, lambda v: 0.0 <= v < 1.0, "in [0, 1) (0 = no gate)")
    reinit = sec.get("gate_reinit_after", int, 3, lambda v: v >= 1, "an integer >= 1")
    sec.finish()
    if "seed" in registry.filter_parameters(kind) and "seed" not in params:
        # random filters (particle filters) draw from the run's seed, distinct per filter name
        params["seed"] = [scenario_seed(cfg), zlib.crc32(name.encode())]
    try:
        flt = registry.make_filter(kind, dynamics, **params)
    except (TypeError, ValueError) as err:
        raise ScenarioError(f"'filters.{name}.params': {err}") from err
    flt.name = name
    flt.gate_probability = gate
    sources = {s: measurement_source(cfg, s, dynamics.labels) for s in inputs}
    _check_initialiser(init, sources, f"filters.{name}.init")
    return FilterStack(name, flt, sources, init, reinit)


def _check_initialiser(init: Initialiser, sources: dict, path: str) -> None:
    """Every measurement the filter consumes offers what its initialiser ``requires`` (ScenarioError if not)."""
    requires = getattr(init, "requires", None)
    for name, source in sources.items():
        if requires is not None and not isinstance(source.model, requires):
            raise ScenarioError(f"'{path}' starts the filter from one measurement through the model's "
                                f"{requires.__name__} methods, which measurement '{name}' "
                                f"({type(source.model).__name__}) does not have; choose another init method "
                                f"(e.g. given) or a sensor whose model has them")


def measurement_source(cfg: dict, name: str, state_labels) -> Sensor | DerivedSource:
    """A sensor or a derived measurement a filter consumes, its model bound to the filter's state layout
    (models on named components, bench_models.labelled; ScenarioError when the state lacks them)."""
    source = derived_source(cfg, name) if name in read_derived(cfg) else build_sensor(cfg, name)
    try:
        source.bind(list(state_labels))
    except ValueError as err:
        raise ScenarioError(f"measurement '{name}' does not fit the filter's state: {err}") from None
    return source
