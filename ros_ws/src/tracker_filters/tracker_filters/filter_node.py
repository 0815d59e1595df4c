"""``filter_node``: a bench filter in any ROS 2 graph, configured by its parameters alone (no launcher, no
lock-step: bench_engine.bench_node.standalone_main). The filter's core is the node kind ``filter``
(tracker_filters.filter_stage)."""

from __future__ import annotations

from bench_engine.bench_node import standalone_main
from bench_engine.stage_node import StageNode
from tracker_filters.filter_stage import FILTER


def main() -> int:
    return standalone_main(StageNode, FILTER.name)
