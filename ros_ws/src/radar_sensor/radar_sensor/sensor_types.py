"""Registered sensor types, what they build (:class:`Sensor`) and the scenario's sensors, without building
them (cheap to import: the graph reads these for every node; the builders are in radar_sensor.sensor)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from bench_engine import plugins
from bench_engine.config import ScenarioError
from bench_engine.labels import AZIMUTHS
from bench_engine.settings import (
    POSITIVE,
    PROBABILITY,
    SectionReader,
    Settings,
    read_entries,
    read_key,
    setting,
    variant,
)
from bench_models.models import MeasurementModel, check_angles

if TYPE_CHECKING:
    from orbit_sim.truth import Earth


@dataclass
class Sensor:
    """What a sensor type builds (radar_sensor.sensor): a measurement model with its noise R, detection
    probability, sample rate, frame and visibility."""

    name: str
    kind: str
    model: MeasurementModel
    R: np.ndarray  # measurement noise covariance (d, d)
    p_detect: float
    every_n_steps: int
    frame_id: str
    visible: Callable[[np.ndarray, float], bool]

    def __post_init__(self) -> None:
        self._chol = np.linalg.cholesky(self.R)
        try:
            check_angles(self.model)
        except ValueError as err:
            raise ScenarioError(f"sensor '{self.name}': {err}") from None
        self._azimuths = [i for i, label in enumerate(self.model.labels) if label in AZIMUTHS]

    def noise(self, t: float, rng: np.random.Generator) -> np.ndarray:
        """One draw of the measurement noise at time t: white, N(0, R)."""
        return self._chol @ rng.standard_normal(self.R.shape[0])

    def bind(self, state_labels: list[str]) -> None:
        """Bind a model defined on named state components (bench_models.labelled) to the observed state's
        layout; other models fit one layout already and are kept."""
        if hasattr(self.model, "for_state"):
            self.model = self.model.for_state(state_labels)

    def observe(self, x_true: np.ndarray, t: float, step: int, rng: np.random.Generator) -> np.ndarray | None:
        """A noisy measurement of x_true at time t, or None (off-cycle, not visible or missed detection).

        Random draws happen only on sample steps where the target is visible, always in the same order
        (detection, then noise), so a seed reproduces a run exactly.
        """
        if step % self.every_n_steps or not self.visible(x_true, t):
            return None
        detected = rng.random() < self.p_detect
        noise = self.noise(t, rng)
        if not detected:
            return None
        z = self.model.h(x_true, t) + noise
        z[self._azimuths] = np.mod(z[self._azimuths], 2.0 * np.pi)
        return z


@dataclass(frozen=True, kw_only=True)
class SensorSettings(Settings):
    """One entry of ``sensors`` (or of ``cluttered_sensors``): a registered sensor type with its sampling, and
    the type's own keys (its :class:`SensorType`'s ``settings``)."""

    type: str = setting(
        doc="a registered sensor type (entry-point group tracking_bench.sensors)",
        choices=lambda: plugins.names("sensors"),
    )
    interval: float = setting(unit="s", doc="time between two samples: a whole multiple of time.dt", check=POSITIVE)
    p_detect: float = setting(
        1.0, doc="probability that a sample where the target is visible gives a measurement", check=PROBABILITY
    )
    model: Settings = variant(
        "type", lambda: plugins.names("sensors"), lambda name: plugins.load("sensors", name).settings
    )


@dataclass(frozen=True)
class SensorType:
    """A registered sensor type: the ROS message type it publishes, its keys (a Settings class: ``settings``)
    and its builder (sensor settings, sensor name, Earth model, sample every n steps) -> Sensor."""

    message_type: str
    settings: type
    build: Callable[[SensorSettings, str, Earth, int], Sensor]


def sensor_names(cfg: dict) -> list[str]:
    """The scenario's sensors, in the order of its ``sensors`` section."""
    return list((cfg.get("sensors") or {}).keys())


def read_sensors(cfg: dict) -> dict[str, SensorSettings]:
    """The ``sensors`` section, read strictly (each sensor's keys; building it checks the rest:
    radar_sensor.sensor.build_sensor)."""
    return read_entries(SensorSettings, cfg.get("sensors"), "sensors")


def sensor_type(cfg: dict, name: str) -> SensorType:
    """The registered type of sensor ``name`` (ScenarioError naming the key and the registered types)."""
    sensors = cfg.get("sensors") or {}
    if name not in sensors:
        raise ScenarioError(f"unknown sensor '{name}'; the scenario has: {sorted(sensors)}")
    return plugins.load("sensors", read_key(SensorSettings, sensors[name], "type", f"sensors.{name}"))


SENSORS = SectionReader(
    "sensors",
    dict[str, SensorSettings],
    "the sensors (node kind sensor): each a registered type with its noise, sampling and visibility",
    read_sensors,
)
