"""Satellite-borne sensors of a formation in ECI: a GNSS receiver's kinematic position fixes and K-band
inter-satellite ranging (paper 002; GRACE).

Both measure named components of the truth state (bench_models.labelled), so they work on any truth that
publishes those labels, and every filter binds the same model to its own state layout.

GNSS noise is white, or a first-order Gauss-Markov process (``correlation_time`` > 0) with the same
stationary standard deviation: e_k = phi e_(k-1) + sqrt(1 - phi^2) L w_k, phi = exp(-dt / tau). Real
kinematic orbits have errors correlated over minutes (multipath, orbit and clock errors of the GPS
satellites); a filter told R = sigma^2 I sees white noise of the right size but not the correlation.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bench_engine.config import ScenarioError, Section
from bench_models.labelled import ComponentModel, RangeRateModel
from orbit_sim.truth import Earth
from radar_sensor.sensor import Sensor
from radar_sensor.sensor_types import SensorType


@dataclass
class GnssReceiver(Sensor):
    """Position fixes whose noise is white or a first-order Gauss-Markov process of stationary covariance R
    (``correlation_time`` > 0), with optional gross outliers (each fix, with ``outlier_probability``, gains an
    error of ``outlier_sigma`` per axis; R does not know it) and outages (no fix inside any
    [start, end] of ``outages``, s since the epoch)."""

    correlation_time: float = 0.0
    outlier_probability: float = 0.0
    outlier_sigma: float = 0.0
    outages: tuple[tuple[float, float], ...] = ()
    _last: tuple[float, np.ndarray] | None = field(default=None, init=False, repr=False)

    def noise(self, t: float, rng: np.random.Generator) -> np.ndarray:
        white = self._chol @ rng.standard_normal(self.R.shape[0])
        if self.correlation_time <= 0.0 or self._last is None or t <= self._last[0]:
            e = white
        else:
            phi = np.exp(-(t - self._last[0]) / self.correlation_time)
            e = phi * self._last[1] + np.sqrt(1.0 - phi * phi) * white
        self._last = (t, e)
        if self.outlier_probability > 0.0 and rng.random() < self.outlier_probability:
            return e + self.outlier_sigma * rng.standard_normal(self.R.shape[0])
        return e


def _components(sec: Section, key: str, n: int | None = None) -> list[str]:
    names = sec.get(key, list)
    if not names or not all(isinstance(c, str) for c in names) or (n is not None and len(names) != n):
        size = f"{n} " if n else ""
        raise ScenarioError(f"'{sec.path}.{key}' must be a list of {size}state labels, got {names!r}")
    return names


def _outages(sec: Section) -> tuple[tuple[float, float], ...]:
    spans = sec.get("outages", list, [])
    if not all(isinstance(s, list) and len(s) == 2 and all(isinstance(v, (int, float)) for v in s) and s[0] <= s[1]
               for s in spans):
        raise ScenarioError(f"'{sec.path}.outages' must be a list of [start, end] times in s (start <= end), "
                            f"got {spans!r}")
    return tuple((float(a), float(b)) for a, b in spans)


def _gnss(sec: Section, name: str, earth: Earth, every: int) -> Sensor:
    """Kinematic GNSS position fix of one satellite: ``position`` names its truth components (e.g. x1 y1 z1)."""
    model = ComponentModel(_components(sec, "position", 3))
    R = sec.positive("sigma_position") ** 2 * np.eye(3)
    tau = sec.get("correlation_time", float, 0.0, lambda v: v >= 0.0, ">= 0 (s; 0 = white noise)")
    outages = _outages(sec)
    return GnssReceiver(name, "gnss", model, R, sec.probability("p_detect", 1.0), every,
                        sec.get("frame_id", str, "eci"), lambda x, t: not any(a <= t <= b for a, b in outages),
                        correlation_time=tau, outlier_probability=sec.probability("outlier_probability", 0.0),
                        outlier_sigma=sec.non_negative("outlier_sigma", 30.0), outages=outages)


def _kbr(sec: Section, name: str, earth: Earth, every: int) -> Sensor:
    """K-band ranging: range and/or range rate between two satellites from their baseline components."""
    components = sec.get("components", list, ["range_rate"])
    if not components or any(c not in ("range", "range_rate") for c in components):
        raise ScenarioError(f"'{sec.path}.components' must be a list of 'range' and/or 'range_rate', "
                            f"got {components!r}")
    model = RangeRateModel(_components(sec, "position", 3), _components(sec, "velocity", 3), components)
    sigmas = [sec.positive(f"sigma_{c}") for c in components]
    return Sensor(name, "kbr", model, np.diag(np.square(sigmas)),
                  sec.probability("p_detect", 1.0), every, sec.get("frame_id", str, "eci"), lambda x, t: True)


GNSS = SensorType("bench_msgs/msg/VectorMeasurement", _gnss)
KBR = SensorType("bench_msgs/msg/VectorMeasurement", _kbr)
