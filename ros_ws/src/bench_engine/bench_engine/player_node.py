"""Bag player node: re-publishes a recorded run's truth and measurements, paced by the estimators' acks.

The recorded serialized messages are published unchanged (``publish(bytes)``), so the header stamps, steps
and noise are exactly those of the original run: any filter can be re-run on identical data. Topics:
``/truth/state``, ``/clock`` and every ``/SENSOR/measurement`` of the original bag. The bag is read in log-time
(sim-time) order and each message replayed with the step it recorded (its ``step`` field), whatever its place
in the file. /clock follows the truth's stamps; a step without truth (a bag made from tracking data without a
reference, bench_ccsds.ingest) takes its measurements' earliest stamp.
"""

from __future__ import annotations

import sys
from collections import defaultdict

from bench_engine.bag_reader import BagReader
from bench_engine.bench_node import node_main
from bench_engine.cdr import deserialize
from bench_engine.graph import CLOCK_TOPIC, TRUTH_TOPIC
from bench_engine.msg_schema import message_class
from bench_engine.source_node import SourceNode


class PlayerNode(SourceNode):
    """Replays truth and measurements from the bag named by the run config's ``replay_bag``."""

    def setup(self) -> None:
        reader = BagReader(self.run["replay_bag"])
        types = reader.topics()
        self.by_step: dict[int, list[tuple[str, bytes]]] = defaultdict(list)
        self.clock_ns: dict[int, int] = {}
        truth_steps = set()
        for topic, type_name, _t, data in reader.messages():
            if topic == CLOCK_TOPIC or topic not in self.spec.publishes:
                continue  # /clock is re-generated from the truth stamps; estimates are not replayed
            msg = deserialize(type_name, data)
            self.by_step[msg.step].append((topic, data))
            stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            if topic == TRUTH_TOPIC:
                self.clock_ns[msg.step] = stamp
                truth_steps.add(msg.step)
            elif msg.step not in truth_steps:
                self.clock_ns[msg.step] = min(stamp, self.clock_ns.get(msg.step, stamp))
        if not self.by_step:
            raise ValueError(f"{self.run['replay_bag']}: no truth or measurement messages to replay")
        self.steps = max(self.by_step) + 1
        super().setup()
        for topic in self.spec.publishes:
            if topic != CLOCK_TOPIC and topic in types:
                self.data_publisher(message_class(types[topic]), topic)

    def publish_step(self, k: int) -> None:
        for topic, data in self.by_step.get(k, ()):
            self.publish_data(topic, data)
        if k in self.clock_ns:
            self.publish_clock(self.clock_ns[k])


def main() -> int:
    return node_main(PlayerNode)


if __name__ == "__main__":
    sys.exit(main())
