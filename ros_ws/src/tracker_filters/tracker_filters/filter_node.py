"""Generic filter node: any filter of the registry on any scenario whose models it fits.

Subscribes the measurement topics of the sensors it consumes (``/SENSOR/measurement``); publishes
``/NAME/estimate`` (bench_msgs/StateEstimate with full covariance and state labels) after every accepted
measurement. Rejected measurements (NaN/inf, out of order, failed update) are logged and skipped;
recoveries (covariance repaired, particle cloud re-initialised) are logged as warnings.
"""
from __future__ import annotations

import sys
from functools import partial

import numpy as np

from bench_msgs.msg import StateEstimate
from orbit_sim.bench_node import BenchNode, node_main
from orbit_sim.graph import estimate_topic, measurement_topic
from radar_sensor.messages import MESSAGE_CLASSES, from_message
from tracker_filters.builders import build_filter_stack


class FilterNode(BenchNode):
    """State estimator fed by measurement topics; the filter type comes from the scenario."""

    def setup(self) -> None:
        self.stack = build_filter_stack(self.cfg, self.get_name())
        self.pub = self.data_publisher(StateEstimate, estimate_topic(self.get_name()))
        self.consumed = 0
        for sensor in self.stack.sensors:
            topic = measurement_topic(sensor)
            self.data_subscription(MESSAGE_CLASSES[self.spec.subscribes[topic]], topic,
                                   partial(self._on_measurement, sensor))

    def _on_measurement(self, sensor_name: str, msg) -> None:
        self.consumed += 1
        try:
            self._process(sensor_name, msg)
        finally:
            self.ack(msg.step, self.consumed)

    def _process(self, sensor_name: str, msg) -> None:
        t, z, R = from_message(msg)
        sensor = self.stack.sensors[sensor_name]
        flt = self.stack.filter
        log = self.get_logger()
        if not flt.initialised:
            if not (np.all(np.isfinite(z)) and np.all(np.isfinite(R))):
                log.warning(f"rejected non-finite first measurement at step {msg.step}; waiting for the next")
                return
            x0, P0 = self.stack.initialise(z, R, sensor, t)
            flt.initialise(x0, P0, t)
            self._publish(msg, float("nan"))
            return
        result = flt.process(t, z, R, sensor.model)
        for warning in result.warnings:
            log.warning(warning)
        if not result.accepted:
            log.warning(f"rejected measurement at step {msg.step}: {result.reason}")
            return
        self._publish(msg, result.nis)

    def _publish(self, meas_msg, nis: float) -> None:
        flt = self.stack.filter
        out = StateEstimate()
        out.header.stamp = meas_msg.header.stamp
        out.header.frame_id = flt.dynamics.frame
        out.step = meas_msg.step
        out.filter_name = self.get_name()
        out.labels = flt.labels
        out.state = flt.x.tolist()
        out.covariance = flt.P.ravel().tolist()
        out.nis = float(nis)
        diag = flt.diagnostics()
        out.diagnostic_names = list(diag)
        out.diagnostic_values = [float(v) for v in diag.values()]
        self.pub.publish(out)


NODE_CLASS = FilterNode


def main() -> int:
    return node_main(FilterNode)


if __name__ == "__main__":
    sys.exit(main())
