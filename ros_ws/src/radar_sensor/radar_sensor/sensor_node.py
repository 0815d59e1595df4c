"""Sensor node: turns each truth sample into a noisy measurement (or none) and acknowledges the step.

Subscribes ``/truth/state``; publishes ``/NAME/measurement`` (RangeAzEl or VectorMeasurement, stamped with
the truth's sim time, frame in header.frame_id). Which sensor it is comes from the scenario's
``sensors.NAME`` section (type, noise, P_D, rate, mask).
"""
from __future__ import annotations

import sys

import numpy as np

from bench_msgs.msg import TruthState
from orbit_sim.bench_node import BenchNode, node_main, stamp_to_ns
from orbit_sim.graph import TRUTH_TOPIC, measurement_topic
from radar_sensor.messages import MESSAGE_CLASSES, to_message
from radar_sensor.sensor import build_sensor


class SensorNode(BenchNode):
    """Simulated sensor (ground radar, inter-satellite radio, relative position)."""

    def setup(self) -> None:
        name = self.get_name()
        self.sensor = build_sensor(self.cfg, name)
        seed = int(self.run.get("seed", self.cfg.get("seed", 0)))
        index = [s.name for s in self.graph.of_kind("sensor")].index(name)
        self.rng = np.random.default_rng([seed, 1000 + index])
        topic = measurement_topic(name)
        self.msg_class = MESSAGE_CLASSES[self.spec.publishes[topic]]
        self.pub = self.data_publisher(self.msg_class, topic)
        self.published = 0
        self.data_subscription(TruthState, TRUTH_TOPIC, self._on_truth)

    def _on_truth(self, msg: TruthState) -> None:
        t_ns = stamp_to_ns(msg.header.stamp)
        x = np.asarray(msg.state, dtype=float)
        z = self.sensor.observe(x, t_ns * 1e-9, msg.step, self.rng)
        if z is not None:
            self.pub.publish(to_message(self.msg_class, z, self.sensor.R, self.sensor.model.labels, t_ns,
                                        self.sensor.frame_id, msg.step, self.get_name()))
            self.published += 1
        self.ack(msg.step, self.published)


NODE_CLASS = SensorNode


def main() -> int:
    return node_main(SensorNode)


if __name__ == "__main__":
    sys.exit(main())
