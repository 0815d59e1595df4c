"""Truth propagator node: publishes the scenario's ground truth and /clock, one lock-step at a time.

Topics: publishes ``/truth/state`` (bench_msgs/TruthState, frame in header.frame_id) and ``/clock``.
"""
from __future__ import annotations

import sys

from bench_msgs.msg import TruthState
from orbit_sim.bench_node import node_main, ns_to_stamp
from orbit_sim.graph import TRUTH_TOPIC
from orbit_sim.source_node import SourceNode
from orbit_sim.truth import build_truth


class TruthNode(SourceNode):
    """Truth propagator (Cowell two-body + J2) and pacing source of the run."""

    def setup(self) -> None:
        self.truth = build_truth(self.cfg)
        self.steps = self.truth.grid.steps
        super().setup()
        self.truth_pub = self.data_publisher(TruthState, TRUTH_TOPIC)

    def publish_step(self, k: int) -> None:
        t_ns = self.truth.grid.t_ns(k)
        msg = TruthState()
        ns_to_stamp(t_ns, msg.header.stamp)
        msg.header.frame_id = self.truth.frame
        msg.step = k
        msg.labels = list(self.truth.labels)
        msg.state = self.truth.states[k].tolist()
        self.truth_pub.publish(msg)
        self.publish_clock(t_ns)


NODE_CLASS = TruthNode


def main() -> int:
    return node_main(TruthNode)


if __name__ == "__main__":
    sys.exit(main())
