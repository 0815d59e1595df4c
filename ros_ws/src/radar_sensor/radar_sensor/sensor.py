"""A sensor = a measurement model + its noise, detection probability, visibility and sample rate.

Built from the scenario's ``sensors.NAME`` section by :func:`build_sensor`; the sensor node and every filter
use the same object, so simulation and estimation agree on the model (frames, Earth rotation, conventions).
Sensor types are registered in the entry-point group ``tracking_bench.sensors`` as :class:`SensorType`
objects (the message type they publish and their builder): a new sensor type is a new module and one line in
``setup.py``. :class:`Sensor` and :class:`SensorType` are defined in radar_sensor.sensor_types (cheap to
import) and imported from here too; this module holds the builders.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench_engine.config import ScenarioError
from bench_engine.settings import POSITIVE, Settings, between, setting
from bench_engine.timegrid import build_time
from bench_models.isl import RangeAzElModel, RelativePositionModel
from bench_models.radar import GroundRadarModel
from orbit_sim.truth import Earth, build_earth
from radar_sensor.sensor_types import Sensor, SensorSettings, SensorType, read_sensors, sensor_type


def build_sensor(cfg: dict, name: str) -> Sensor:
    """Build sensor ``name`` from ``sensors.NAME``; raises ScenarioError naming any bad key."""
    stype = sensor_type(cfg, name)
    settings = read_sensors(cfg)[name]
    sensor = stype.build(settings, name, build_earth(cfg), every_n_steps(settings, cfg))
    sensor.kind = settings.type
    return sensor


def every_n_steps(sensor: SensorSettings, cfg: dict) -> int:
    """The sensor's ``interval`` as a whole number of time steps (ScenarioError if it is not one)."""
    interval, dt = sensor.interval, build_time(cfg).dt
    n = int(round(interval / dt))
    if n < 1 or abs(n * dt - interval) > 1e-9 * max(interval, 1.0):
        raise ScenarioError(f"'{sensor.where('interval')}' ({interval} s) must be a whole multiple of time.dt ({dt} s)")
    return n


LATITUDE = between(-90.0, 90.0)


@dataclass(frozen=True, kw_only=True)
class Station(Settings):
    """A ground station's geodetic position (WGS-84)."""

    lat_deg: float = setting(unit="deg", doc="geodetic latitude", check=LATITUDE)
    lon_deg: float = setting(unit="deg", doc="longitude, east positive")
    alt_m: float = setting(0.0, unit="m", doc="height above the ellipsoid")


@dataclass(frozen=True, kw_only=True)
class GroundRadar(Settings):
    """``ground_radar``: range, azimuth, elevation (and range rate) of the target from a ground station."""

    station: Station = setting(doc="the radar's site")
    range_rate: bool = setting(False, doc="also measure the range rate")
    sigma_range: float = setting(unit="m", doc="range noise (1σ)", check=POSITIVE)
    sigma_azimuth: float = setting(unit="rad", doc="azimuth noise (1σ)", check=POSITIVE)
    sigma_elevation: float = setting(unit="rad", doc="elevation noise (1σ)", check=POSITIVE)
    sigma_range_rate: float | None = setting(
        None, unit="m/s", doc="range-rate noise (1σ); with range_rate only", check=POSITIVE
    )
    min_elevation_deg: float = setting(
        0.0, unit="deg", doc="the target is visible above this elevation", check=LATITUDE
    )
    frame_id: str | None = setting(None, doc="header.frame_id of the measurements", default_text="NAME_enu")

    def validate(self, path: str) -> None:
        if self.range_rate != (self.sigma_range_rate is not None):
            raise ScenarioError(f"'{path}.sigma_range_rate' is needed with range_rate: true, and only then")


def _ground_radar(s: SensorSettings, name: str, earth: Earth, every: int) -> Sensor:
    radar, st = s.model, s.model.station
    model = GroundRadarModel(
        np.radians(st.lat_deg), np.radians(st.lon_deg), st.alt_m, theta0=earth.theta0, with_range_rate=radar.range_rate
    )
    sigmas = [radar.sigma_range, radar.sigma_azimuth, radar.sigma_elevation]
    if radar.range_rate:
        sigmas.append(radar.sigma_range_rate)
    mask = np.radians(radar.min_elevation_deg)
    return Sensor(
        name,
        "ground_radar",
        model,
        np.diag(np.square(sigmas)),
        s.p_detect,
        every,
        radar.frame_id or f"{name}_enu",
        lambda x, t: float(model.elevation(x, t)) >= mask,
    )


@dataclass(frozen=True, kw_only=True)
class IslRadio(Settings):
    """``isl_radio``: range, azimuth, elevation of the deputy seen from the chief (paper 001 eqs. 6-8 with
    convention along_radial, paper 004 eqs. 29-32 with radial_along_normal)."""

    convention: str = setting(
        choices=("radial_along_normal", "along_radial"), doc="the LVLH axes the angles are measured in"
    )
    sigma_range: float = setting(unit="m", doc="range noise (1σ)", check=POSITIVE)
    sigma_azimuth: float = setting(unit="rad", doc="azimuth noise (1σ)", check=POSITIVE)
    sigma_elevation: float = setting(unit="rad", doc="elevation noise (1σ)", check=POSITIVE)
    frame_id: str = setting("lvlh", doc="header.frame_id of the measurements")


def _isl_radio(s: SensorSettings, name: str, earth: Earth, every: int) -> Sensor:
    isl = s.model
    sigmas = [isl.sigma_range, isl.sigma_azimuth, isl.sigma_elevation]
    return Sensor(
        name,
        "isl_radio",
        RangeAzElModel(isl.convention),
        np.diag(np.square(sigmas)),
        s.p_detect,
        every,
        isl.frame_id,
        lambda x, t: True,
    )


@dataclass(frozen=True, kw_only=True)
class RelativePosition(Settings):
    """``relative_position``: the deputy's position in the chief's LVLH frame (paper 004 eq. 28)."""

    sigma_position: float = setting(unit="m", doc="noise per axis (1σ)", check=POSITIVE)
    frame_id: str = setting("lvlh", doc="header.frame_id of the measurements")


def _relative_position(s: SensorSettings, name: str, earth: Earth, every: int) -> Sensor:
    return Sensor(
        name,
        "relative_position",
        RelativePositionModel(),
        s.model.sigma_position**2 * np.eye(3),
        s.p_detect,
        every,
        s.model.frame_id,
        lambda x, t: True,
    )


GROUND_RADAR = SensorType("bench_msgs/msg/RangeAzEl", GroundRadar, _ground_radar)
ISL_RADIO = SensorType("bench_msgs/msg/RangeAzEl", IslRadio, _isl_radio)
RELATIVE_POSITION = SensorType("bench_msgs/msg/VectorMeasurement", RelativePosition, _relative_position)
