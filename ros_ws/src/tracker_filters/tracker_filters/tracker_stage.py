"""The tracker node's core, registered as the node kind ``tracker`` (role estimator) for every entry of the
scenario's ``trackers`` section that the run selects (``--estimators`` or the scenario's ``estimators``):

    trackers:
      gnn:
        filter: kf                # an entry of the ``filters`` section: each track's filter (type, dynamics,
                                  # initialiser, parameters), built by tracker_filters.builders
        detections: cam           # a cluttered sensor (radar_sensor.clutter); its measurement model is used
        gate_probability: 0.999   # P_G of the chi-square gate (default 0.999)
        max_misses: 10            # delete the track after this many consecutive misses (default: never)

Subscribes ``/DETECTIONS/detections`` (bench_msgs/DetectionSet); publishes ``/NAME/estimate``
(bench_msgs/StateEstimate) for its track after every detection set once the track exists, so the scorer
scores it like a filter. NIS is the update's (NaN when the track coasted); the diagnostics are ``associated``
(1 when a detection updated the track or started it, else 0), ``candidates`` (detections in the set),
``gated`` (detections in the track's gate) and the filter's own.
"""

from __future__ import annotations

from dataclasses import dataclass

from bench_engine.config import ScenarioError
from bench_engine.graph import ESTIMATE_TYPE, NodeKind, NodeSpec, estimate_topic
from bench_engine.settings import Check, SectionReader, Settings, at_least, read_entries, setting
from bench_engine.stage import DetectionSet, Estimate, Outputs, python_log
from radar_sensor.clutter import DETECTION_SET_TYPE, build_cluttered, detections_topic
from radar_sensor.clutter import names as cluttered_names
from tracker_filters.filter_settings import state_labels
from tracker_filters.filter_stage import build_stack

SECTION = "trackers"


@dataclass(frozen=True, kw_only=True)
class TrackerConfig(Settings):
    """One entry of ``trackers`` (the module docstring)."""

    filter: str = setting(
        doc="an entry of the filters section: each track's filter (type, dynamics, initialiser, parameters)"
    )
    detections: str = setting(doc="a cluttered sensor (an entry of cluttered_sensors); its measurement model is used")
    gate_probability: float = setting(
        0.999, check=Check(lambda v: 0.0 < v < 1.0, "in (0, 1)"), doc="P_G of the chi-square gate"
    )
    max_misses: int | None = setting(
        None, check=at_least(1), doc="delete the track after this many consecutive misses (null: never)"
    )


def read_trackers(cfg: dict) -> dict[str, TrackerConfig]:
    """The ``trackers`` section, read strictly: ``filter`` names a filter, ``detections`` a cluttered sensor."""
    out = read_entries(TrackerConfig, cfg.get(SECTION), SECTION)
    filters, cluttered = list(cfg.get("filters") or {}), cluttered_names(cfg) if out else []
    for conf in out.values():
        for key, allowed in (("filter", filters), ("detections", cluttered)):
            if getattr(conf, key) not in allowed:
                raise ScenarioError(f"'{conf.where(key)}' must be one of {allowed}, got {getattr(conf, key)!r}")
    return out


TRACKERS = SectionReader(
    SECTION, dict[str, TrackerConfig], "trackers of sets of detections (node kind tracker: estimators)", read_trackers
)


def tracker_config(cfg: dict, name: str) -> TrackerConfig:
    trackers = read_trackers(cfg)
    if name not in trackers:
        raise ScenarioError(f"unknown tracker '{name}'; the scenario has: {sorted(trackers)}")
    return trackers[name]


def build_tracker(cfg: dict, name: str):
    """The Tracker of ``trackers.NAME`` over fresh filters of its ``filter`` entry (ScenarioError on any bad
    key)."""
    from tracker_filters.tracker import Tracker  # data association and scipy: only where a tracker is built

    conf = tracker_config(cfg, name)
    sensor = build_cluttered(cfg, conf.detections).sensor
    stack = build_stack(cfg, conf.filter)

    def new_filter():
        flt = build_stack(cfg, conf.filter).filter
        flt.name = name
        return flt

    return Tracker(
        new_filter,
        lambda z, R, t: stack.initialise(z, R, sensor, t),
        sensor.model,
        conf.gate_probability,
        max_misses=conf.max_misses,
    )


class TrackerStage:
    """Detection sets in, the track's estimate out."""

    def __init__(self, cfg: dict, name: str, run: dict | None = None) -> None:
        self.name, self.topic = name, estimate_topic(name)
        self.tracker = build_tracker(cfg, name)
        self.log = python_log(name)

    def on_input(self, topic: str, d: DetectionSet) -> Outputs:
        report = self.tracker.step(d.t, d.Z, d.R)
        for reason in report.rejected:
            self.log("warning", f"step {d.step}: update rejected: {reason}")
        for result in report.results:
            for warning in result.warnings if result is not None else []:
                self.log("warning", warning)
        if report.deleted:
            self.log("info", f"step {d.step}: track deleted after {self.tracker.max_misses} consecutive misses")
        if report.started:
            self.log("info", f"step {d.step}: track started")
        if not self.tracker.tracks:
            return []
        flt = self.tracker.tracks[0].filter
        result = report.results[0] if report.results and not report.started else None
        updated = result is not None and result.accepted
        gated = (
            float(report.hypotheses.gated[0].sum())
            if report.hypotheses is not None and not report.started
            else float("nan")
        )
        diagnostics = {
            "associated": 1.0 if (report.started or updated) else 0.0,
            "candidates": float(len(d.Z)),
            "gated": gated,
            **flt.diagnostics(),
        }
        return [
            (
                self.topic,
                Estimate(
                    d.step,
                    d.t_ns,
                    flt.dynamics.frame,
                    self.name,
                    flt.labels,
                    flt.x.copy(),
                    flt.P.copy(),
                    result.nis if updated else float("nan"),
                    diagnostics,
                ),
            )
        ]


def _spec(cfg: dict, name: str) -> NodeSpec:
    conf = tracker_config(cfg, name)
    return NodeSpec(
        name,
        "tracker",
        publishes={estimate_topic(name): ESTIMATE_TYPE},
        subscribes={detections_topic(conf.detections): DETECTION_SET_TYPE},
        labels={estimate_topic(name): state_labels(cfg, conf.filter)},
    )


TRACKER = NodeKind(
    "tracker",
    "estimator",
    "bench_engine.stage_node:StageNode",
    instances=lambda cfg, names: list(names),
    spec=_spec,
    check=lambda cfg, name: build_tracker(cfg, name),
    stage=TrackerStage,
    claims=lambda cfg: list(read_trackers(cfg)),
)
