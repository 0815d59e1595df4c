"""The sensor node's core: each truth sample becomes a noisy measurement (or none), registered as the node
kind ``sensor`` for every entry of the scenario's ``sensors`` section.

Subscribes ``/truth/state``; publishes ``/NAME/measurement`` (the message type of the sensor's registered
type), stamped with the truth's sim time and step, its frame in header.frame_id.
"""

from __future__ import annotations

import numpy as np

from bench_engine.graph import TRUTH_TOPIC, TRUTH_TYPE, NodeKind, NodeSpec, measurement_topic
from bench_engine.scenario import scenario_seed
from bench_engine.stage import Measurement, Outputs, TruthSample, python_log
from radar_sensor.sensor import build_sensor
from radar_sensor.sensor_types import sensor_names, sensor_type


class SensorStage:
    """Simulated sensor (ground radar, inter-satellite radio, relative position, ...)."""

    def __init__(self, cfg: dict, name: str, run: dict) -> None:
        self.name = name
        self.sensor = build_sensor(cfg, name)
        seed = int(run.get("seed", scenario_seed(cfg)))
        self.rng = np.random.default_rng([seed, 1000 + sensor_names(cfg).index(name)])
        self.topic = measurement_topic(name)
        self.labels = list(self.sensor.model.labels)
        self.log = python_log(name)
        self._bound_to: list[str] | None = None

    def on_input(self, topic: str, truth: TruthSample) -> Outputs:
        if self._bound_to != truth.labels:
            self.sensor.bind(truth.labels)
            self._bound_to = list(truth.labels)
        z = self.sensor.observe(truth.state, truth.t_ns * 1e-9, truth.step, self.rng)
        if z is None:
            return []
        return [
            (
                self.topic,
                Measurement(truth.step, truth.t_ns, self.sensor.frame_id, self.name, z, self.sensor.R, self.labels),
            )
        ]


def _spec(cfg: dict, name: str) -> NodeSpec:
    return NodeSpec(
        name,
        "sensor",
        publishes={measurement_topic(name): sensor_type(cfg, name).message_type},
        subscribes={TRUTH_TOPIC: TRUTH_TYPE},
    )


def _check(cfg: dict, name: str) -> None:
    build_sensor(cfg, name)


SENSOR = NodeKind(
    "sensor",
    "sensor",
    "bench_engine.stage_node:StageNode",
    instances=lambda cfg, requested: sensor_names(cfg),
    spec=_spec,
    check=_check,
    stage=SensorStage,
)
