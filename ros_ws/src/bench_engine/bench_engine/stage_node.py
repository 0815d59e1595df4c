"""The ROS shell of every sensor and estimator: decode, call the kind's core, publish, acknowledge.

Which core it drives comes from the node's kind (bench_engine.graph.NodeKind.stage); the topics and their
types from the run's graph; the message <-> item conversions from the codecs registered per message type.
Messages travel as CDR bytes, built and read by bench_engine.cdr (light message objects: the codecs see the
same attributes as rclpy's classes, at a fraction of the cost). Everything the core logs goes to the node's
ROS logger.
"""
from __future__ import annotations

import sys
from functools import partial

from bench_engine.bench_node import BenchNode, node_main
from bench_engine.graph import node_kinds
from bench_engine.stage import codec


class StageNode(BenchNode):
    """A sensor or estimator node: one registered core between its input and output topics."""

    def setup(self) -> None:
        self.stage = node_kinds()[self.spec.kind].stage(self.cfg, self.get_name(), self.run)
        self.stage.log = self._log
        self.consumed = 0
        self.outputs = {topic: self.item_publisher(topic, type_name)
                        for topic, type_name in self.spec.publishes.items()}
        for topic, type_name in self.spec.subscribes.items():
            self.item_subscription(topic, type_name, partial(self._on_input, topic, codec(type_name)))

    def _log(self, level: str, text: str) -> None:
        getattr(self.get_logger(), level)(text)

    def _on_input(self, topic: str, decoder, msg) -> None:
        self.consumed += 1
        try:
            for out_topic, item in self.stage.on_input(topic, decoder.decode(msg)):
                self.outputs[out_topic](item)
        finally:
            self.ack(msg.step, self.consumed)


def main() -> int:
    return node_main(StageNode)


if __name__ == "__main__":
    sys.exit(main())
