"""A cluttered sensor: every sample step, a set of detections (bench_msgs/DetectionSet) that holds the target's
measurement with probability P_D and Poisson(``clutter_rate``) false detections, uniform in a box of
``clutter_halfwidth`` (one half-width per measurement component) around the true measurement. Which one is
the target's is not said: a tracker has to associate them (tracker_filters.association).

Registered as the node kind ``cluttered_sensor`` (role sensor) for every entry of the scenario's
``cluttered_sensors`` section; each entry is a registered sensor type's section (its model, noise, P_D,
interval) plus the clutter keys:

    cluttered_sensors:
      cam: {type: relative_position, interval: 1.0, sigma_position: 0.5, p_detect: 0.9,
            clutter_rate: 2.0, clutter_halfwidth: [20.0, 20.0, 20.0]}
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench_engine import plugins
from bench_engine.config import ScenarioError
from bench_engine.graph import TRUTH_TOPIC, TRUTH_TYPE, NodeKind, NodeSpec
from bench_engine.scenario import scenario_seed
from bench_engine.settings import Check, SectionReader, read_entries, setting
from bench_engine.stage import DetectionSet, Outputs, TruthSample, python_log
from orbit_sim.truth import build_earth
from radar_sensor.sensor import every_n_steps
from radar_sensor.sensor_types import SensorSettings

SECTION = "cluttered_sensors"
DETECTION_SET_TYPE = "bench_msgs/msg/DetectionSet"
STREAM = 2000
"""Random stream of cluttered sensor i: [seed, STREAM + i] (plain sensors use 1000 + i)."""


def detections_topic(name: str) -> str:
    return f"/{name}/detections"


@dataclass
class ClutteredSensor:
    sensor: object
    """The radar_sensor.sensor.Sensor that measures the target (model, R, P_D, rate, visibility)."""
    clutter_rate: float
    halfwidth: np.ndarray

    def observe(self, x_true: np.ndarray, t: float, step: int, rng: np.random.Generator) -> np.ndarray | None:
        """Detections (N, d) of one step, in random order, or None off the sensor's sample steps."""
        s = self.sensor
        if step % s.every_n_steps or not s.visible(x_true, t):
            return None
        z_true = s.model.h(x_true, t)
        target = s.observe(x_true, t, step, rng)
        # false detections: N ~ Poisson(clutter_rate), each uniform in the box z_true +- halfwidth
        clutter = z_true + rng.uniform(-1.0, 1.0, (rng.poisson(self.clutter_rate), len(z_true))) * self.halfwidth
        clutter[:, s._azimuths] = np.mod(clutter[:, s._azimuths], 2.0 * np.pi)  # as the sensor wraps azimuth
        Z = clutter if target is None else np.vstack([target, clutter])
        return Z[rng.permutation(len(Z))]


@dataclass(frozen=True, kw_only=True)
class ClutteredSettings(SensorSettings):
    """One entry of ``cluttered_sensors``: a registered sensor type's keys plus the clutter's."""

    clutter_rate: float = setting(
        doc="mean number of false detections per sample (Poisson)",
        check=Check(lambda v: 0.0 <= v < float("inf"), "finite and >= 0"),
    )
    clutter_halfwidth: list[float] = setting(
        doc="half-width of the box around the true measurement the false "
        "detections fall in, one per measurement component [its units]",
        check=Check(lambda v: all(np.isfinite(v)) and all(w > 0 for w in v), "values > 0"),
    )


def read_section(cfg: dict) -> dict[str, ClutteredSettings]:
    """The ``cluttered_sensors`` section, read strictly."""
    return read_entries(ClutteredSettings, cfg.get(SECTION), SECTION)


def names(cfg: dict) -> list[str]:
    """The scenario's cluttered sensors, in section order."""
    return list(read_section(cfg))


def build_cluttered(cfg: dict, name: str) -> ClutteredSensor:
    """Build ``cluttered_sensors.NAME``: a registered sensor type's keys plus clutter_rate, clutter_halfwidth."""
    sections = read_section(cfg)
    if name not in sections:
        raise ScenarioError(f"unknown cluttered sensor '{name}'; the scenario has: {sorted(sections)}")
    s = sections[name]
    sensor = plugins.load("sensors", s.type).build(s, name, build_earth(cfg), every_n_steps(s, cfg))
    halfwidth = np.asarray(s.clutter_halfwidth, dtype=float)
    if halfwidth.shape != (len(sensor.model.labels),):
        raise ScenarioError(
            f"'{s.where('clutter_halfwidth')}' must hold {len(sensor.model.labels)} values > 0 "
            f"({', '.join(sensor.model.labels)}), got {halfwidth.tolist()}"
        )
    return ClutteredSensor(sensor, s.clutter_rate, halfwidth)


CLUTTERED_SENSORS = SectionReader(
    SECTION,
    dict[str, ClutteredSettings],
    "sensors whose samples are sets of detections with clutter (node kind cluttered_sensor; a tracker associates them)",
    read_section,
)


class ClutteredSensorStage:
    """Each truth sample becomes one DetectionSet (possibly empty) on the sensor's sample steps."""

    def __init__(self, cfg: dict, name: str, run: dict) -> None:
        self.name = name
        self.cluttered = build_cluttered(cfg, name)
        seed = int(run.get("seed", scenario_seed(cfg)))
        self.rng = np.random.default_rng([seed, STREAM + names(cfg).index(name)])
        s = self.cluttered.sensor
        self.labels, self.topic = list(s.model.labels), detections_topic(name)
        self.log = python_log(name)

    def on_input(self, topic: str, truth: TruthSample) -> Outputs:
        Z = self.cluttered.observe(truth.state, truth.t_ns * 1e-9, truth.step, self.rng)
        if Z is None:
            return []
        R = np.broadcast_to(self.cluttered.sensor.R, (len(Z),) + self.cluttered.sensor.R.shape)
        return [
            (
                self.topic,
                DetectionSet(truth.step, truth.t_ns, self.cluttered.sensor.frame_id, self.name, self.labels, Z, R),
            )
        ]


CLUTTERED_SENSOR = NodeKind(
    "cluttered_sensor",
    "sensor",
    "bench_engine.stage_node:StageNode",
    instances=lambda cfg, requested: names(cfg),
    spec=lambda cfg, name: NodeSpec(
        name,
        "cluttered_sensor",
        publishes={detections_topic(name): DETECTION_SET_TYPE},
        subscribes={TRUTH_TOPIC: TRUTH_TYPE},
    ),
    check=build_cluttered,
    stage=ClutteredSensorStage,
)
