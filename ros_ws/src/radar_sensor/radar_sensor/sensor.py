"""A sensor = a measurement model + its noise, detection probability, visibility and sample rate.

Built from the scenario's ``sensors.NAME`` section by :func:`build_sensor`; the sensor node and every filter
use the same object, so simulation and estimation agree on the model (frames, Earth rotation, conventions).
Sensor types are registered in the entry-point group ``tracking_bench.sensors`` as :class:`SensorType`
objects (the message type they publish and their builder): a new sensor type is a new module and one line in
``setup.py``. :class:`Sensor` and :class:`SensorType` are defined in radar_sensor.sensor_types (cheap to
import) and imported from here too; this module holds the builders.
"""
from __future__ import annotations

import numpy as np

from bench_engine.config import ScenarioError, Section
from bench_engine.timegrid import build_time
from orbit_sim.truth import Earth, build_earth
from bench_models.isl import RangeAzElModel, RelativePositionModel
from bench_models.radar import GroundRadarModel
from radar_sensor.sensor_types import Sensor, SensorType, sensor_type


def build_sensor(cfg: dict, name: str) -> Sensor:
    """Build sensor ``name`` from ``sensors.NAME``; raises ScenarioError naming any bad key."""
    stype = sensor_type(cfg, name)
    sec = Section(cfg["sensors"][name], f"sensors.{name}")
    kind = sec.get("type", str)
    sensor = stype.build(sec, name, build_earth(cfg), every_n_steps(sec, cfg))
    sensor.kind = kind
    sec.finish()
    return sensor


def every_n_steps(sec: Section, cfg: dict) -> int:
    """The section's ``interval`` as a whole number of time steps (ScenarioError if it is not one)."""
    interval = sec.positive("interval")
    dt = build_time(cfg).dt
    n = int(round(interval / dt))
    if n < 1 or abs(n * dt - interval) > 1e-9 * max(interval, 1.0):
        raise ScenarioError(f"'{sec.path}.interval' ({interval} s) must be a whole multiple of time.dt ({dt} s)")
    return n


def _ground_radar(sec: Section, name: str, earth: Earth, every: int) -> Sensor:
    st = sec.section("station", default_empty=False)
    lat = np.radians(st.get("lat_deg", float, check=lambda v: -90 <= v <= 90, expect="in [-90, 90]"))
    lon = np.radians(st.get("lon_deg", float))
    alt = st.get("alt_m", float, 0.0)
    st.finish()
    with_rr = sec.get("range_rate", bool, False)
    model = GroundRadarModel(lat, lon, alt, theta0=earth.theta0, with_range_rate=with_rr)
    sigmas = [sec.positive("sigma_range"), sec.positive("sigma_azimuth"), sec.positive("sigma_elevation")]
    if with_rr:
        sigmas.append(sec.positive("sigma_range_rate"))
    mask = np.radians(sec.get("min_elevation_deg", float, 0.0,
                              lambda v: -90 <= v <= 90, "in [-90, 90]"))
    return Sensor(name, "ground_radar", model, np.diag(np.square(sigmas)), sec.probability("p_detect", 1.0),
                  every, sec.get("frame_id", str, f"{name}_enu"),
                  lambda x, t: float(model.elevation(x, t)) >= mask)


def _isl_radio(sec: Section, name: str, earth: Earth, every: int) -> Sensor:
    """Inter-satellite radio: range, azimuth, elevation of the deputy seen from the chief (paper 001 eqs.
    6-8 with convention "along_radial", paper 004 eqs. 29-32 with "radial_along_normal")."""
    model = RangeAzElModel(sec.choice("convention", ("radial_along_normal", "along_radial")))
    sigmas = [sec.positive("sigma_range"), sec.positive("sigma_azimuth"), sec.positive("sigma_elevation")]
    return Sensor(name, "isl_radio", model, np.diag(np.square(sigmas)), sec.probability("p_detect", 1.0), every,
                  sec.get("frame_id", str, "lvlh"), lambda x, t: True)


def _relative_position(sec: Section, name: str, earth: Earth, every: int) -> Sensor:
    """Relative position in the chief's LVLH frame (paper 004 eq. 28)."""
    sigma = sec.positive("sigma_position")
    return Sensor(name, "relative_position", RelativePositionModel(), sigma**2 * np.eye(3),
                  sec.probability("p_detect", 1.0), every, sec.get("frame_id", str, "lvlh"), lambda x, t: True)


GROUND_RADAR = SensorType("bench_msgs/msg/RangeAzEl", _ground_radar)
ISL_RADIO = SensorType("bench_msgs/msg/RangeAzEl", _isl_radio)
RELATIVE_POSITION = SensorType("bench_msgs/msg/VectorMeasurement", _relative_position)
