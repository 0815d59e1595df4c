"""Scenario -> filter objects: dynamics model, filter, initialiser and the sensors a filter consumes.

A filter node's behaviour comes entirely from ``filter_defaults`` merged with ``filters.NAME``:

    type: ukf                 # any name in tracker_filters.registry.FILTERS
    sensors: [radar]          # measurement topics it consumes
    dynamics: {model: orbit_j2, sigma_accel: 5.0e-3}
    init: {method: first_scan, velocity_sigma: 1000.0}
    params: {alpha: 1.0e-3}   # constructor parameters of the filter type
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from orbit_sim.config import ScenarioError, Section
from orbit_sim.graph import filter_config, sensor_names
from orbit_sim.truth import build_earth
from radar_sensor.sensor import Sensor, build_sensor
from tracker_filters import registry
from tracker_filters.filter_base import Filter
from tracker_filters.initialisation import initial_state_from_scan
from tracker_filters.models import DynamicsModel
from tracker_filters.orbit_dynamics import OrbitJ2Dynamics

Initialiser = Callable[[np.ndarray, np.ndarray, Sensor, float], tuple[np.ndarray, np.ndarray]]


@dataclass
class FilterStack:
    """Everything a filter node needs."""

    name: str
    filter: Filter
    sensors: dict[str, Sensor]
    initialise: Initialiser


def _orbit_j2(sec: Section, cfg: dict) -> DynamicsModel:
    earth = build_earth(cfg)
    return OrbitJ2Dynamics(sec.non_negative("sigma_accel"), mu=earth.mu, j2=earth.j2, re=earth.re)


DYNAMICS: dict[str, Callable[[Section, dict], DynamicsModel]] = {"orbit_j2": _orbit_j2}


def build_dynamics(sec: Section, cfg: dict) -> DynamicsModel:
    model = sec.choice("model", sorted(DYNAMICS))
    dynamics = DYNAMICS[model](sec, cfg)
    sec.finish()
    return dynamics


def _first_scan(sec: Section) -> Initialiser:
    velocity_sigma = sec.positive("velocity_sigma")

    def initialise(z: np.ndarray, R: np.ndarray, sensor: Sensor, t: float) -> tuple[np.ndarray, np.ndarray]:
        return initial_state_from_scan(z, R, sensor.model, t, velocity_sigma)
    return initialise


INITIALISERS: dict[str, Callable[[Section], Initialiser]] = {"first_scan": _first_scan}


def build_initialiser(sec: Section) -> Initialiser:
    method = sec.choice("method", sorted(INITIALISERS))
    init = INITIALISERS[method](sec)
    sec.finish()
    return init


def build_filter_stack(cfg: dict, name: str) -> FilterStack:
    """Build filter node ``name``; every bad key or value raises ScenarioError naming it."""
    sec = Section(filter_config(cfg, name), f"filters.{name}")
    kind = sec.choice("type", sorted(registry.FILTERS))
    inputs = sec.get("sensors", list, sensor_names(cfg))
    dynamics = build_dynamics(sec.section("dynamics", default_empty=False), cfg)
    init = build_initialiser(sec.section("init", default_empty=False))
    params = sec.get("params", dict, {})
    sec.finish()
    try:
        flt = registry.make_filter(kind, dynamics, **params)
    except (TypeError, ValueError) as err:
        raise ScenarioError(f"'filters.{name}.params': {err}") from err
    flt.name = name
    return FilterStack(name, flt, {s: build_sensor(cfg, s) for s in inputs}, init)
