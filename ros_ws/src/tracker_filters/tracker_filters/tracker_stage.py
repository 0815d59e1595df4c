"""The tracker node's core, registered as the node kind ``tracker`` (role estimator) for every entry of the
scenario's ``trackers`` section:

    trackers:
      gnn: {filter: kf, detections: cam, gate_probability: 0.999}

``filter`` names an entry of the ``filters`` section (its type, dynamics, initialiser and parameters build each
track's filter); ``detections`` a cluttered sensor (radar_sensor.clutter), whose measurement model the updates
use. Subscribes ``/DETECTIONS/detections``; publishes ``/NAME/estimate`` (bench_msgs/StateEstimate) for the
track after every detection set once it exists, with the diagnostics ``associated`` (1 or 0) and
``candidates`` (detections in the set), so the scorer scores it like a filter.
"""
from __future__ import annotations

from dataclasses import dataclass

from bench_engine.config import ScenarioError, Section
from bench_engine.graph import ESTIMATE_TYPE, NodeKind, NodeSpec, estimate_topic
from bench_engine.stage import DetectionSet, Estimate, Outputs, python_log

SECTION = "trackers"


@dataclass
class TrackerConfig:
    filter: str
    detections: str
    gate_probability: float


def read_trackers(cfg: dict) -> dict[str, TrackerConfig]:
    """The ``trackers`` section, read strictly (registered section reader)."""
    sec = Section(cfg.get(SECTION), SECTION)
    out = {}
    for name in sec.keys():
        entry = sec.section(name)
        out[name] = TrackerConfig(entry.choice("filter", list((cfg.get("filters") or {}).keys())),
                                  entry.choice("detections", list((cfg.get("cluttered_sensors") or {}).keys())),
                                  entry.get("gate_probability", float, 0.999, lambda v: 0.0 < v < 1.0, "in (0, 1)"))
        entry.finish()
    sec.finish()
    return out


def build_tracker(cfg: dict, name: str):
    from radar_sensor.clutter import build_cluttered
    from tracker_filters.builders import build_filter_stack
    from tracker_filters.tracker import Tracker
    trackers = read_trackers(cfg)
    if name not in trackers:
        raise ScenarioError(f"unknown tracker '{name}'; the scenario has: {sorted(trackers)}")
    conf = trackers[name]
    sensor = build_cluttered(cfg, conf.detections).sensor
    stack = build_filter_stack(cfg, conf.filter)

    def new_filter():
        flt = build_filter_stack(cfg, conf.filter).filter
        flt.name = name
        return flt

    return Tracker(new_filter, lambda z, R, t: stack.initialise(z, R, sensor, t), sensor.model,
                   conf.gate_probability), conf


class TrackerStage:
    def __init__(self, cfg: dict, name: str, run: dict | None = None) -> None:
        self.name, self.topic = name, estimate_topic(name)
        self.tracker, _ = build_tracker(cfg, name)
        self.log = python_log(name)

    def on_input(self, topic: str, d: DetectionSet) -> Outputs:
        report = self.tracker.step(d.t, d.Z, d.R)
        for reason in report.rejected:
            self.log("warning", f"step {d.step}: update rejected: {reason}")
        if not self.tracker.tracks:
            return []
        flt = self.tracker.tracks[0].filter
        associated = 1.0 if report.started or (report.associated and report.associated[0] >= 0) else 0.0
        return [(self.topic, Estimate(d.step, d.t_ns, flt.dynamics.frame, self.name, flt.labels, flt.x.copy(),
                                      flt.P.copy(), float("nan"),
                                      {"associated": associated, "candidates": float(len(d.Z))}))]


def _spec(cfg: dict, name: str) -> NodeSpec:
    from radar_sensor.clutter import detections_topic
    return NodeSpec(name, "tracker", publishes={estimate_topic(name): ESTIMATE_TYPE},
                    subscribes={detections_topic(read_trackers(cfg)[name].detections): ""})


TRACKER = NodeKind("tracker", "estimator", "bench_engine.stage_node:StageNode",
                   instances=lambda cfg, requested: list(read_trackers(cfg)), spec=_spec,
                   check=lambda cfg, name: build_tracker(cfg, name), stage=TrackerStage)
