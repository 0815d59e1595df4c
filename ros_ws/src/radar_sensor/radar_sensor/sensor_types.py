"""Registered sensor types and the scenario's sensors, without building them (cheap to import: the graph
reads these for every node)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

from bench_engine import plugins
from bench_engine.config import ScenarioError, Section

if TYPE_CHECKING:
    from orbit_sim.truth import Earth
    from radar_sensor.sensor import Sensor


@dataclass(frozen=True)
class SensorType:
    """A registered sensor type: the ROS message type it publishes and how to build it from its section
    (section, sensor name, Earth model, sample every n steps) -> Sensor."""

    message_type: str
    build: Callable[[Section, str, Earth, int], Sensor]


def sensor_names(cfg: dict) -> list[str]:
    """The scenario's sensors, in the order of its ``sensors`` section."""
    return list((cfg.get("sensors") or {}).keys())


def sensor_type(cfg: dict, name: str) -> SensorType:
    """The registered type of sensor ``name`` (ScenarioError naming the key and the registered types)."""
    sensors = cfg.get("sensors") or {}
    if name not in sensors:
        raise ScenarioError(f"unknown sensor '{name}'; the scenario has: {sorted(sensors)}")
    section = sensors[name] if isinstance(sensors[name], dict) else {}
    return plugins.load("sensors", Section(section, f"sensors.{name}").choice("type", plugins.names("sensors")))
