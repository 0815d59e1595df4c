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
from bench_engine.cdr import deserialize
from bench_engine.graph import node_kinds
from bench_engine.msg_schema import message_class
from bench_engine.stage import Item, codec
from bench_engine.views import item_publishers, warm

warm()  # compiled once where nodes are forked from (bench_engine.views.warm)


class StageNode(BenchNode):
    """A sensor or estimator node: one registered core between its input and output topics.

    Input contract: a message that cannot be decoded into its item (malformed bytes, inconsistent sizes) or
    that carries no valid stamp is logged as a warning and skipped; it never reaches the core nor ends the
    node. (The core itself rejects non-finite values and out-of-order stamps.)"""

    def setup(self) -> None:
        self.stage = node_kinds()[self.spec.kind].stage(self.settings, self.get_name(), self.run or {})
        self.stage.log = self._log
        self.consumed = 0
        self._last_step = 0
        self.outputs = item_publishers(self, self.spec.publishes)  # with the standard views (bench_engine.views)
        self._resolved: dict[str, str] = {}
        """Graph topic -> the name it resolved to (namespace, remaps), as the node's warnings name it."""
        for topic, type_name in self.spec.subscribes.items():
            sub = self.data_subscription(
                message_class(type_name), topic, partial(self._on_input, topic, type_name, codec(type_name)), raw=True
            )
            self._resolved[topic] = sub.topic_name

    def _log(self, level: str, text: str) -> None:
        getattr(self.get_logger(), level)(text)

    def _on_input(self, topic: str, type_name: str, decoder, data: bytes) -> None:
        self.consumed += 1
        try:
            item = _decoded(type_name, decoder, data)
        except Exception as err:  # noqa: BLE001 - whatever the bytes make the decoder raise is the message's fault
            self.get_logger().warning(
                f"{self._resolved[topic]}: skipped a malformed {type_name} message ({type(err).__name__}: {err})"
            )
            item = None
        try:
            if item is not None:
                self._last_step = max(self._last_step, item.step)
                for out_topic, out in self.stage.on_input(topic, item):
                    self.outputs[out_topic](out)
        finally:
            if not self.standalone:
                self.ack(self._last_step, self.consumed)


def _decoded(type_name: str, decoder, data: bytes) -> Item:
    """The item of a message's CDR bytes; raises on bytes that are no such message or a stamp out of range."""
    item = decoder.decode(deserialize(type_name, data))
    if item.t_ns < 0 or item.step < 0:
        raise ValueError(f"negative stamp or step (t = {item.t_ns} ns, step {item.step})")
    return item


def main() -> int:
    return node_main(StageNode)


if __name__ == "__main__":
    sys.exit(main())
