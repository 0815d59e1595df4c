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
from bench_engine.config import ScenarioError, Section
from bench_engine.scenario import scenario_seed
from bench_engine.graph import TRUTH_TOPIC, TRUTH_TYPE, NodeKind, NodeSpec
from bench_engine.stage import DetectionSet, Outputs, TruthSample, python_log
from orbit_sim.truth import build_earth
from radar_sensor.sensor import every_n_steps

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


def names(cfg: dict) -> list[str]:
    """The scenario's cluttered sensors, in section order (ScenarioError if the section is not a mapping)."""
    return Section(cfg.get(SECTION), SECTION).keys()


def build_cluttered(cfg: dict, name: str) -> ClutteredSensor:
    """Build ``cluttered_sensors.NAME``: a registered sensor type's keys plus clutter_rate, clutter_halfwidth."""
    sections = Section(cfg.get(SECTION), SECTION)
    if name not in sections.keys():
        raise ScenarioError(f"unknown cluttered sensor '{name}'; the scenario has: {sorted(sections.keys())}")
    sec = sections.section(name, default_empty=False)
    kind = sec.choice("type", plugins.names("sensors"))
    rate = sec.get("clutter_rate", float, check=lambda v: 0.0 <= v < float("inf"), expect="finite and >= 0")
    values = sec.get("clutter_halfwidth", list)
    try:
        halfwidth = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ScenarioError(f"'{sec.path}.clutter_halfwidth' must be a list of numbers, got {values!r}") from None
    sensor = plugins.load("sensors", kind).build(sec, name, build_earth(cfg), every_n_steps(sec, cfg))
    sec.finish()
    if halfwidth.shape != (len(sensor.model.labels),) or not np.all(np.isfinite(halfwidth) & (halfwidth > 0)):
        raise ScenarioError(f"'{sec.path}.clutter_halfwidth' must hold {len(sensor.model.labels)} values > 0 "
                            f"({', '.join(sensor.model.labels)}), got {halfwidth.tolist()}")
    return ClutteredSensor(sensor, rate, halfwidth)


def read_section(cfg: dict) -> dict[str, ClutteredSensor]:
    """The scenario's ``cluttered_sensors`` section, every entry built (registered section reader)."""
    return {name: build_cluttered(cfg, name) for name in names(cfg)}


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
        return [(self.topic, DetectionSet(truth.step, truth.t_ns, self.cluttered.sensor.frame_id, self.name,
                                          self.labels, Z, R))]


CLUTTERED_SENSOR = NodeKind(
    "cluttered_sensor", "sensor", "bench_engine.stage_node:StageNode", instances=lambda cfg, requested: names(cfg),
    spec=lambda cfg, name: NodeSpec(name, "cluttered_sensor", publishes={detections_topic(name): DETECTION_SET_TYPE},
                                    subscribes={TRUTH_TOPIC: TRUTH_TYPE}),
    check=build_cluttered, stage=ClutteredSensorStage)
