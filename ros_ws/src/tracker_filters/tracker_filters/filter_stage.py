"""The filter node's core: any registered filter on any scenario whose models it fits, registered as the
node kind ``filter`` for the run's selected filters (``--estimators`` or the scenario's ``estimators``: the
selected names that no other kind's section defines; a name the ``filters`` section does not define is a filter
of that type).

Subscribes the measurement topics of the sensors it consumes (``/SENSOR/measurement``); publishes
``/NAME/estimate`` (bench_msgs/StateEstimate with full covariance and state labels) after every accepted
measurement. Measurements are ordered by their sim time (``header.stamp``), never by the bench's ``step``
counter, so a publisher outside the bench (``step`` left at 0) feeds the filter the same way. Rejected
measurements (NaN/inf, a time not after the last one from the same sensor, gated by the filter's NIS gate,
failed update) are logged and skipped;
recoveries (covariance repaired, particle cloud re-initialised) are logged as warnings. The filters are
imported only when one is built (:func:`build_stack`: every node of a run reads the kind to build the graph).
"""

from __future__ import annotations

import numpy as np

from bench_engine.config import ScenarioError
from bench_engine.graph import ESTIMATE_TYPE, NodeKind, NodeSpec, estimate_topic, measurement_topic
from bench_engine.stage import Estimate, Measurement, Outputs, python_log
from radar_sensor.sensor_types import sensor_names
from tracker_filters.derived import read_derived
from tracker_filters.filter_settings import filter_config, filter_key, state_labels


def build_stack(cfg: dict, name: str):
    """The filter stack of ``filters.NAME`` (tracker_filters.builders.build_filter_stack), for this module and
    the other estimator kinds built on a filter (fixed-lag smoother, tracker)."""
    from tracker_filters.builders import build_filter_stack  # every filter and scipy: only where one is built

    return build_filter_stack(cfg, name)


class FilterStage:
    """State estimator fed by measurement items; the filter type comes from the scenario."""

    def __init__(self, cfg: dict, name: str, run: dict | None = None) -> None:
        self.name = name
        self.stack = build_stack(cfg, name)
        self.sensor_of = {measurement_topic(s): s for s in self.stack.sensors}
        self.topic = estimate_topic(name)
        self.log = python_log(name)
        self.last_t_ns: dict[str, int] = {}
        self.gated_in_a_row = 0

    def on_input(self, topic: str, m: Measurement) -> Outputs:
        sensor = self.stack.sensors[self.sensor_of[topic]]
        flt = self.stack.filter
        if topic in self.last_t_ns and m.t_ns <= self.last_t_ns[topic]:
            self.log(
                "warning",
                f"rejected measurement at step {m.step}: out-of-order measurement from "
                f"{sensor.name} (duplicated or out-of-order: t = {m.t:.9f} s is not after its "
                f"last, t = {self.last_t_ns[topic] * 1e-9:.9f} s)",
            )
            return []
        self.last_t_ns[topic] = m.t_ns
        if not flt.initialised or self.gated_in_a_row >= self.stack.reinit_after_gated:
            return self._start(m, sensor)
        result = flt.process(m.t, m.z, m.R, sensor.model)
        for warning in result.warnings:
            self.log("warning", warning)
        self.gated_in_a_row = self.gated_in_a_row + 1 if result.gated else 0
        if not result.accepted:
            self.log("warning", f"rejected measurement at step {m.step}: {result.reason}")
            return []
        return [self._estimate(m, result.nis)]

    def _start(self, m: Measurement, sensor) -> Outputs:
        """Initialise from m: the first measurement, or after ``reinit_after_gated`` gated ones in a row (the
        prediction lost the target, e.g. across a long data gap: every later measurement would be gated too)."""
        if not (np.all(np.isfinite(m.z)) and np.all(np.isfinite(m.R))):
            self.log(
                "warning", f"rejected non-finite measurement at step {m.step} while (re)starting; waiting for the next"
            )
            return []
        if self.stack.filter.initialised:
            self.log(
                "warning",
                f"{self.gated_in_a_row} measurements in a row were gated: the filter lost lock and "
                f"restarts from the measurement of step {m.step}",
            )
        self.gated_in_a_row = 0
        x0, P0 = self.stack.initialise(m.z, m.R, sensor, m.t)
        self.stack.filter.initialise(x0, P0, m.t)
        return [self._estimate(m, float("nan"))]

    def _estimate(self, m: Measurement, nis: float) -> tuple[str, Estimate]:
        flt = self.stack.filter
        return self.topic, Estimate(
            m.step,
            m.t_ns,
            flt.dynamics.frame,
            self.name,
            flt.labels,
            flt.x.copy(),
            flt.P.copy(),
            nis,
            flt.diagnostics(),
        )


def _spec(cfg: dict, name: str) -> NodeSpec:
    sensors = sensor_names(cfg) + list(read_derived(cfg))
    inputs = filter_key(cfg, name, "sensors") or sensor_names(cfg)
    unknown = [s for s in inputs if s not in sensors]
    if unknown:
        raise ScenarioError(f"'filters.{name}.sensors' names unknown sensor(s) {unknown}; allowed: {sorted(sensors)}")
    return NodeSpec(
        name,
        "filter",
        publishes={estimate_topic(name): ESTIMATE_TYPE},
        subscribes={measurement_topic(s): "" for s in inputs},
        labels={estimate_topic(name): state_labels(cfg, name)},
    )


FILTER_READS = ("scenario", "seed", "time", "earth", "truth", "sensors", "derived_measurements")
"""Scenario sections a filter's core reads besides its own settings: the sensor and derived measurement
models it consumes, the Earth and reference orbit of its dynamics, the seed of a random filter."""


def _reads(cfg: dict, name: str) -> dict:
    """A filter node's settings (its ROS parameters): FILTER_READS and ``filters.NAME`` merged with
    ``filter_defaults``."""
    settings = {key: cfg[key] for key in FILTER_READS if key in cfg}
    settings["filters"] = {name: filter_config(cfg, name)}
    return settings


def _check(cfg: dict, name: str) -> None:
    build_stack(cfg, name)


FILTER = NodeKind(
    "filter",
    "estimator",
    "bench_engine.stage_node:StageNode",
    instances=lambda cfg, names: list(names),
    spec=_spec,
    check=_check,
    stage=FilterStage,
    reads=_reads,
    claims=lambda cfg: list(cfg.get("filters") or {}),
    takes_unclaimed=True,
)
