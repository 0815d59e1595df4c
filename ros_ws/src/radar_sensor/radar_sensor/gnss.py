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

from bench_engine.config import ScenarioError
from bench_engine.settings import NON_NEGATIVE, POSITIVE, PROBABILITY, Check, Settings, setting
from bench_models.labelled import ComponentModel, RangeRateModel
from orbit_sim.truth import Earth
from radar_sensor.sensor import Sensor
from radar_sensor.sensor_types import SensorSettings, SensorType


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


def _labels(n: int) -> Check:
    return Check(lambda names: len(names) == n, f"a list of {n} state labels")


@dataclass(frozen=True, kw_only=True)
class Gnss(Settings):
    """``gnss``: kinematic position fixes of one satellite, white or Gauss-Markov noise, outliers, outages."""

    position: list[str] = setting(doc="the truth's components it measures (e.g. x1 y1 z1)", check=_labels(3))
    sigma_position: float = setting(unit="m", doc="noise per axis (1σ, stationary)", check=POSITIVE)
    correlation_time: float = setting(
        0.0,
        unit="s",
        doc="Gauss-Markov correlation time of the noise (0: white)",
        check=Check(lambda v: v >= 0.0, ">= 0 (s; 0 = white noise)"),
    )
    outages: list = setting([], unit="s", doc="[start, end] spans since the epoch without fixes")
    outlier_probability: float = setting(0.0, doc="probability that a fix carries a gross error", check=PROBABILITY)
    outlier_sigma: float = setting(
        30.0, unit="m", doc="a gross error's size per axis (1σ); R does not know it", check=NON_NEGATIVE
    )
    frame_id: str = setting("eci", doc="header.frame_id of the measurements")

    def validate(self, path: str) -> None:
        if not all(
            isinstance(s, list) and len(s) == 2 and all(isinstance(v, (int, float)) for v in s) and s[0] <= s[1]
            for s in self.outages
        ):
            raise ScenarioError(
                f"'{path}.outages' must be a list of [start, end] times in s (start <= end), got {self.outages!r}"
            )


def _gnss(s: SensorSettings, name: str, earth: Earth, every: int) -> Sensor:
    """Kinematic GNSS position fix of one satellite: ``position`` names its truth components (e.g. x1 y1 z1)."""
    g = s.model
    outages = tuple((float(a), float(b)) for a, b in g.outages)
    return GnssReceiver(
        name,
        "gnss",
        ComponentModel(g.position),
        g.sigma_position**2 * np.eye(3),
        s.p_detect,
        every,
        g.frame_id,
        lambda x, t: not any(a <= t <= b for a, b in outages),
        correlation_time=g.correlation_time,
        outlier_probability=g.outlier_probability,
        outlier_sigma=g.outlier_sigma,
        outages=outages,
    )


@dataclass(frozen=True, kw_only=True)
class Kbr(Settings):
    """``kbr``: K-band ranging, range and/or range rate between two satellites from their baseline."""

    components: list[str] = setting(
        ["range_rate"],
        doc="what it measures: range and/or range_rate",
        check=Check(
            lambda c: bool(c) and all(x in ("range", "range_rate") for x in c), "a list of 'range' and/or 'range_rate'"
        ),
    )
    position: list[str] = setting(doc="the truth's baseline position components (e.g. bx by bz)", check=_labels(3))
    velocity: list[str] = setting(doc="the truth's baseline velocity components (e.g. bvx bvy bvz)", check=_labels(3))
    sigma_range: float | None = setting(None, unit="m", doc="range noise (1σ); when range is measured", check=POSITIVE)
    sigma_range_rate: float | None = setting(
        None, unit="m/s", doc="range-rate noise (1σ); when range_rate is measured", check=POSITIVE
    )
    frame_id: str = setting("eci", doc="header.frame_id of the measurements")

    def validate(self, path: str) -> None:
        for c in ("range", "range_rate"):
            if (c in self.components) != (getattr(self, f"sigma_{c}") is not None):
                raise ScenarioError(f"'{path}.sigma_{c}' is needed when {c} is measured (components), and only then")


def _kbr(s: SensorSettings, name: str, earth: Earth, every: int) -> Sensor:
    """K-band ranging: range and/or range rate between two satellites from their baseline components."""
    k = s.model
    model = RangeRateModel(k.position, k.velocity, k.components)
    sigmas = [getattr(k, f"sigma_{c}") for c in k.components]
    return Sensor(name, "kbr", model, np.diag(np.square(sigmas)), s.p_detect, every, k.frame_id, lambda x, t: True)


GNSS = SensorType("bench_msgs/msg/VectorMeasurement", Gnss, _gnss)
KBR = SensorType("bench_msgs/msg/VectorMeasurement", Kbr, _kbr)
