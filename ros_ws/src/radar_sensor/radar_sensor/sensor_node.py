"""``sensor_node``: a bench sensor in any ROS 2 graph, fed by a truth topic and configured by its parameters alone
(no launcher, no lock-step: bench_engine.bench_node.standalone_main). The sensor's core is the node kind
``sensor`` (radar_sensor.sensor_stage)."""

from __future__ import annotations

from bench_engine.bench_node import standalone_main
from bench_engine.stage_node import StageNode
from radar_sensor.sensor_stage import SENSOR


def main() -> int:
    return standalone_main(StageNode, SENSOR.name)
