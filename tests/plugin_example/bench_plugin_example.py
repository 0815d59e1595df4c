"""A throw-away package that extends the bench from outside, as tests/test_registry.py installs it.

It registers (entry points, see entry_points.txt beside this file): a range-only sensor type, an estimator (an EKF with
covariance
inflation), a metric family (the final position error), two node kinds that make a three-stage pipeline sensor -> relay
-> smoother, and the scenario
sections those kinds read. Nothing of the bench is edited to run them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench_engine.graph import ESTIMATE_TYPE, NodeKind, NodeSpec, estimate_topic
from bench_engine.settings import POSITIVE, SectionReader, Settings, read_entries, setting
from bench_engine.stage import Estimate, Measurement, Outputs, python_log
from bench_eval.metric_families import Metric
from radar_sensor.sensor import Sensor
from radar_sensor.sensor_types import SensorType
from tracker_filters.ekf import ExtendedKalmanFilter


class RangeModel:
    """z = |r|, r = the first three state components."""

    labels = ("range",)
    angle_indices = ()

    def h(self, x, t=0.0):
        return np.linalg.norm(np.asarray(x)[..., 0:3], axis=-1)[..., None]

    def jacobian(self, x, t=0.0):
        H = np.zeros((1, len(x)))
        H[0, 0:3] = x[0:3] / np.linalg.norm(x[0:3])
        return H

    def residual(self, z, z_pred):
        return z - z_pred


@dataclass(frozen=True, kw_only=True)
class RangeOnly(Settings):
    """The keys of a range_only sensor (beside type, interval and p_detect)."""

    sigma_range: float = setting(unit="m", doc="range noise (1σ)", check=POSITIVE)


def _build_range_only(s, name: str, earth, every: int) -> Sensor:
    return Sensor(
        name,
        "range_only",
        RangeModel(),
        np.array([[s.model.sigma_range**2]]),
        s.p_detect,
        every,
        "lvlh",
        lambda x, t: True,
    )


RANGE_ONLY = SensorType("bench_msgs/msg/VectorMeasurement", RangeOnly, _build_range_only)


class InflatedEKF(ExtendedKalmanFilter):
    """EKF whose predicted covariance is multiplied by ``inflation`` (a fading-memory filter)."""

    def __init__(self, dynamics, inflation: float = 1.0) -> None:
        if inflation < 1.0:
            raise ValueError(f"inflation must be >= 1, got {inflation}")
        super().__init__(dynamics)
        self.inflation = inflation

    def _predict(self, dt: float) -> None:
        super()._predict(dt)
        self.P = self.P * self.inflation


@dataclass(frozen=True, kw_only=True)
class Link(Settings):
    """One stage of the pipeline."""

    input: str = setting(doc="the topic it consumes")


def read_relays(cfg: dict) -> dict[str, Link]:
    return read_entries(Link, cfg.get("relays"), "relays")


def read_smoothers(cfg: dict) -> dict[str, Link]:
    return read_entries(Link, cfg.get("smoothers"), "smoothers")


RELAYS = SectionReader("relays", dict[str, Link], "relay stages (node kind relay)")
SMOOTHERS = SectionReader("smoothers", dict[str, Link], "smoother stages (node kind smoother)")


class Relay:
    """Stage 2: each measurement becomes an 'estimate' of the measured vector (identity covariance R)."""

    def __init__(self, cfg: dict, name: str, run: dict) -> None:
        self.name, self.log = name, python_log(name)

    def on_input(self, topic: str, m: Measurement) -> Outputs:
        return [(estimate_topic(self.name), Estimate(m.step, m.t_ns, m.frame_id, self.name, list(m.labels), m.z, m.R))]


class Smoother:
    """Stage 3: running mean of stage 2's values."""

    def __init__(self, cfg: dict, name: str, run: dict) -> None:
        self.name, self.log, self.total, self.count = name, python_log(name), 0.0, 0

    def on_input(self, topic: str, e: Estimate) -> Outputs:
        self.total, self.count = self.total + e.x, self.count + 1
        return [
            (
                estimate_topic(self.name),
                Estimate(e.step, e.t_ns, e.frame_id, self.name, e.labels, self.total / self.count, e.P / self.count),
            )
        ]


def _kind(name: str, key: str, stage: type, reader) -> NodeKind:
    return NodeKind(
        name,
        "estimator",
        "bench_engine.stage_node:StageNode",
        instances=lambda cfg, requested: list(reader(cfg)),
        spec=lambda cfg, n: NodeSpec(
            n, name, publishes={estimate_topic(n): ESTIMATE_TYPE}, subscribes={reader(cfg)[n].input: ""}
        ),
        stage=stage,
        order=1 if name == "smoother" else 0,
    )


RELAY = _kind("relay", "relays", Relay, read_relays)
SMOOTHER = _kind("smoother", "smoothers", Smoother, read_smoothers)


def _final_error(tracks: dict, runs: list, options) -> dict:
    return {
        name: {
            "runs": len(group),
            "final_error_m": float(np.mean([np.linalg.norm(tr.error(options.components)[-1]) for tr in group])),
        }
        for name, group in tracks.items()
    }


@dataclass(frozen=True, kw_only=True)
class FinalErrorOptions(Settings):
    """The final_error family's keys of the scoring section."""

    components: list[str] = setting(["x", "y", "z"], doc="the state components whose final error is scored")


FINAL_ERROR = Metric(options=FinalErrorOptions, score=_final_error, series=lambda tracks, runs, options: {})
