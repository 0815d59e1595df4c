"""The pacing source of a run (truth propagator or bag player): readiness barrier, paced stepping, done.

:class:`CoreSourceNode` is the ROS shell of a registered source kind (the truth): it publishes what the kind's
:class:`bench_engine.stage.Source` core returns for each step, encoded by the registered codecs, and /clock.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from rosgraph_msgs.msg import Clock
from std_msgs.msg import String, UInt64

from bench_engine import phases
from bench_engine.bench_node import DATA_QOS, LATCHED_QOS, BenchNode, delivered, node_main, ns_to_stamp
from bench_engine.cdr import deserialize, lite_class, serialize
from bench_engine.graph import (
    ACK_TOPIC,
    ACK_TYPE,
    CLOCK_TOPIC,
    CLOCK_TYPE,
    DONE_TOPIC,
    READY_TOPIC,
    TOTALS_TOPIC,
    node_kinds,
)
from bench_engine.lockstep import Pacer
from bench_engine.timegrid import build_time
from bench_engine.views import item_publishers, warm
from bench_msgs.msg import StepAck

warm()  # compiled once where nodes are forked from (bench_engine.views.warm)


class SourceNode(BenchNode):
    """Publishes steps 0..steps-1 as fast as the slowest consumer allows; subclasses publish one step."""

    steps: int = 0

    def setup(self) -> None:
        self._created = time.monotonic()
        self.pacer = Pacer(
            self.graph.paced_inputs(), window=build_time(self.cfg).pacing_window, weights=self.graph.pacing_weights()
        )
        self._waiting_for = {n.name for n in self.graph.nodes if n.name != self.get_name()}
        self._next = 0
        self._started = None
        self._done_sent = False
        self._ready_deadline = time.monotonic() + float(self.run.get("ready_timeout_s", 60.0))
        self.clock_pub = self.data_publisher(Clock, CLOCK_TOPIC)
        self._clock_msg = lite_class(CLOCK_TYPE)()
        self.done_pub = self.create_publisher(UInt64, DONE_TOPIC, LATCHED_QOS)
        self.totals_pub = self.create_publisher(StepAck, TOTALS_TOPIC, LATCHED_QOS)
        self._reported: dict[str, int] = {}
        """Data topic -> the largest published count a paced node reported for it (final once complete)."""
        self.create_subscription(StepAck, ACK_TOPIC, self._on_ack, DATA_QOS, raw=True)
        self.create_subscription(String, READY_TOPIC, self._on_ready_msg, LATCHED_QOS)
        self._watchdog = self.create_timer(0.5, self._check_start_timeout)

    def publish_step(self, k: int) -> None:
        """Publish everything of step k (subclass)."""
        raise RuntimeError("SourceNode subclasses implement publish_step")

    def publish_data(self, topic: str, msg) -> None:
        """Publish on a data topic and count it for the pacer (its subscribers acknowledge it)."""
        super().publish_data(topic, msg)
        self.pacer.on_published(topic)

    def publish_clock(self, t_ns: int) -> None:
        msg = self._clock_msg
        ns_to_stamp(t_ns, msg.clock)
        self.clock_pub.publish(serialize(CLOCK_TYPE, msg))
        self.published[CLOCK_TOPIC] += 1

    # -- protocol ---------------------------------------------------------------------------------------
    def _on_ready_msg(self, msg: String) -> None:
        self._waiting_for.discard(msg.data)
        self._maybe_start()

    def on_ready(self) -> None:
        self._maybe_start()

    def _maybe_start(self) -> None:
        if self._started is None and self._announced and not self._waiting_for:
            self._started = time.monotonic()
            phases.mark("stepping_start", self.get_name(), self.run.get("out"))
            self._watchdog.cancel()
            self.get_logger().info(
                f"all nodes ready after {self._started - self._created:.2f} s; stepping {self.steps} steps"
            )
            self._pump()

    def _check_start_timeout(self) -> None:
        if self._started is None and time.monotonic() > self._ready_deadline:
            self.fail(f"nodes never became ready: {sorted(self._waiting_for)} (did one of them fail at start-up?)")

    def _on_ack(self, data: bytes) -> None:
        msg = deserialize(ACK_TYPE, data)
        published = dict(zip(msg.topics, msg.published.tolist()))
        self.pacer.on_ack(msg.node, msg.count, published)
        for topic, count in published.items():
            self._reported[topic] = max(self._reported.get(topic, 0), int(count))
        if self._started is not None:
            self._pump()

    def _pump(self) -> None:
        while self._next < self.steps and self.pacer.can_publish():
            self.publish_step(self._next)
            self._next += 1
        if self._next >= self.steps and not self._done_sent and self.pacer.complete():
            self._finish_run()

    def _finish_run(self) -> None:
        self._done_sent = True
        stepping = time.monotonic() - self._started
        phases.mark("stepping_end", self.get_name(), self.run.get("out"))
        # Complete: every paced node's last acknowledgement is in, so the counts it reported are final.
        totals = StepAck(node=self.get_name(), step=self.steps - 1)
        counts = {**self._reported, **self.published}
        totals.topics = sorted(counts)
        totals.published = [counts[t] for t in totals.topics]
        self.totals_pub.publish(totals)
        self.done_pub.publish(UInt64(data=self.steps - 1))
        # every node must hear "done" before this node (the only publisher of it) goes away
        if delivered([self.done_pub, self.totals_pub]):
            self.get_logger().warning(f"{DONE_TOPIC}: not every node acknowledged it in time")
        phases.mark("done_acked", self.get_name(), self.run.get("out"))
        timing = {
            "startup_s": round(self._started - self._created, 3),
            "stepping_s": round(stepping, 3),
            "steps": self.steps,
        }
        self.get_logger().info(
            f"{self.steps} steps in {stepping:.2f} s ({self.steps / max(stepping, 1e-9):.0f} steps/s)"
        )
        if self.run.get("out"):
            Path(self.run["out"], "timing.json").write_text(json.dumps(timing, indent=1))
        self.flush_and_finish()


class CoreSourceNode(SourceNode):
    """The ROS shell of a registered source kind: publishes its core's items of each step, then /clock."""

    def setup(self) -> None:
        self.core = node_kinds()[self.spec.kind].stage(self.settings, self.get_name(), self.run)
        self.steps = self.core.steps
        super().setup()
        self.outputs = item_publishers(
            self, {topic: type_name for topic, type_name in self.spec.publishes.items() if topic != CLOCK_TOPIC}
        )  # with the standard views (bench_engine.views)

    def publish_step(self, k: int) -> None:
        for topic, item in self.core.outputs(k):
            self.outputs[topic](item)
        self.publish_clock(self.core.t_ns(k))


def main() -> int:
    return node_main(CoreSourceNode)


if __name__ == "__main__":
    sys.exit(main())
