"""Recorder node: writes every data topic of the run, as serialized CDR, to a rosbag2-style MCAP bag.

Subscribes with ``raw=True`` (no deserialisation) to every topic the graph's nodes publish. On ``/sim/done``
it drains what is still in flight and closes the bag as soon as every topic holds the final count the source
announced on ``/sim/totals`` (without them, once the other nodes have left and nothing arrived for a while);
SIGINT/SIGTERM also close it, so an interrupted run leaves a complete, readable bag. Once FLUSH_SIM_S of sim
time (counted in /clock messages) and FLUSH_WALL_S of wall time have both passed since the last flush
(bench_engine.bag_writer.FlushSchedule), it ends the bag's chunk and writes it out, so a recorder killed
outright loses at most the longer of the two: bench_engine.recovery rebuilds the bag from what is on disk.

Log times are sim time (bench_engine.sim_clock.SimClock, decided per topic from its type when it is declared): a
message's log and publish times are its ``header.stamp`` if its type opens with a std_msgs/Header, a
rosgraph_msgs/Clock's own time, and otherwise the latest /clock received (the run's start before the first),
so Foxglove, PlotJuggler, rosbags or ``ros2 bag play`` show and play the run on the sim's time line. The wall
time of the first message and the span to the last go to the metadata's ``custom_data``
(:data:`WALL_START_KEY`, :data:`WALL_DURATION_KEY`, in ns).
"""

from __future__ import annotations

import sys
import time
from functools import partial
from pathlib import Path

from bench_engine import phases, yamlio
from bench_engine.bag_writer import BagWriter, FlushSchedule
from bench_engine.bench_node import DATA_QOS, LATCHED_QOS, BenchNode, node_main
from bench_engine.graph import CLOCK_TOPIC, TOTALS_TOPIC
from bench_engine.msg_schema import message_class
from bench_engine.sim_clock import SimClock
from bench_engine.timegrid import build_time
from bench_msgs.msg import StepAck

FLUSH_SIM_S = 1.0
"""Least sim time between two flushes of the bag."""
FLUSH_WALL_S = 0.5
"""Least wall time between two flushes of the bag."""
STRANDED_POLL_S = 0.5
"""Wall time between two polls of the subscriptions' queues for messages without an executor event."""
IDLE_AFTER_DONE_S = 0.5
MAX_DRAIN_S = 15.0
WALL_START_KEY = "wall_clock_start_ns"
WALL_DURATION_KEY = "wall_clock_duration_ns"


class RecorderNode(BenchNode):
    """rosbag2-compatible MCAP recorder.

    It runs rclpy's EventsExecutor like every node. Under load that executor misses the events of some
    messages, which then wait in their subscription's queue: a poll (``_take_stranded``) takes them. The
    recorder is paced like the other consumers (the truth runs at most its window ahead of the recorder's
    acknowledgements), so it never falls far behind, and it closes the bag once every topic holds the count the
    truth announced on /sim/totals. (Unpaced and without the poll, an EventsExecutor recorder lost messages for
    good under load.)"""

    def setup(self) -> None:
        self.bag = BagWriter(self.run["bag_dir"])
        # The scorer needs the scenario (sensor models, scoring options): the bag carries its run config.
        Path(self.run["bag_dir"], "run_config.yaml").write_text(yamlio.dump(self.run, sort_keys=False))
        self.counts: dict[str, int] = {}
        grid = build_time(self.cfg)
        self.sim_clock = SimClock(grid.start_ns)
        self._wall_first_ns = self._wall_last_ns = 0  # wall times of the first and the last message
        self._flushes = FlushSchedule(max(1, round(FLUSH_SIM_S / grid.dt)), FLUSH_WALL_S)
        self._last_rx = time.monotonic()
        self._drain_started = None
        self.stranded = 0
        self.consumed = 0
        self._totals: dict[str, int] | None = None
        self.create_subscription(StepAck, TOTALS_TOPIC, self._on_totals, LATCHED_QOS)
        self._subs = {}
        for topic, type_name in sorted(self.spec.subscribes.items()):
            self.bag.add_topic(topic, type_name, DATA_QOS)
            self.sim_clock.add_topic(topic, type_name)
            self.counts[topic] = 0
            self._subs[topic] = self.data_subscription(
                message_class(type_name), topic, partial(self._on_message, topic), raw=True
            )
        self.create_timer(STRANDED_POLL_S, self._take_stranded)

    def _on_message(self, topic: str, data: bytes) -> None:
        sim_ns = self.sim_clock.log_time_ns(topic, data)
        self.bag.write(topic, data, sim_ns, sim_ns)
        now_ns = time.time_ns()
        self._wall_first_ns = self._wall_first_ns or now_ns
        self._wall_last_ns = now_ns
        self.counts[topic] += 1
        if topic != CLOCK_TOPIC:  # acknowledged like any paced node's input (the clock is not paced)
            self.consumed += 1
            self.ack(self.consumed, self.consumed)
        self._last_rx = time.monotonic()
        if topic == CLOCK_TOPIC and self._flushes.due():
            self.bag.flush()
        if self._drain_started is not None and self._totals is not None:
            self._close_if_drained()

    def _take_stranded(self) -> int:
        """Record messages that wait in a subscription's queue without an executor event: rclpy's
        EventsExecutor can miss events under load, and such a message, already acknowledged to its publisher,
        would otherwise never be delivered. Returns how many were taken."""
        taken = 0
        for topic, sub in self._subs.items():
            while not self.bag.closed:
                with sub.handle:
                    item = sub.handle.take_message(sub.msg_type, True)
                if item is None:
                    break
                self._on_message(topic, item[0])
                taken += 1
        self.stranded += taken
        return taken

    def _on_totals(self, msg: StepAck) -> None:
        self._totals = dict(zip(msg.topics, (int(n) for n in msg.published)))
        if self._drain_started is not None:
            self._check_drained()

    def on_done(self, last_step: int) -> None:
        self._drain_started = time.monotonic()
        self.create_timer(0.1, self._check_drained)
        self._check_drained()

    def _has_everything(self) -> bool:
        """Every recorded topic holds the count the source reported as final (/sim/totals)."""
        return self._totals is not None and all(n >= self._totals.get(t, 0) for t, n in self.counts.items())

    def _check_drained(self) -> None:
        if not self.finished:
            self._take_stranded()
        self._close_if_drained()

    def _close_if_drained(self) -> None:
        """Close the bag once it holds every message of the run; without the totals (or if they never add up),
        once the other nodes are gone and nothing came for IDLE_AFTER_DONE_S, or after a longer silence."""
        if self.finished:
            return
        if self._has_everything():
            stranded = f"; {self.stranded} of them taken by the queue poll" if self.stranded else ""
            self.get_logger().info(
                f"every message of the run is in ({sum(self.counts.values())}{stranded}): bag closed"
            )
            self.close()
            self.finished = True
            return
        now = time.monotonic()
        idle = now - self._last_rx
        others_gone = all(self.count_publishers(t) == 0 for t in self.counts)
        if (
            (idle > IDLE_AFTER_DONE_S and others_gone)
            or idle > 2 * IDLE_AFTER_DONE_S
            or now - self._drain_started > MAX_DRAIN_S
        ):
            missing = (
                {t: self._totals.get(t, 0) - n for t, n in self.counts.items() if self._totals.get(t, 0) > n}
                if self._totals is not None
                else "no totals received"
            )
            self.get_logger().warning(f"bag closed after {idle:.1f} s without messages; missing: {missing}")
            self.close()
            self.finished = True

    def close(self) -> None:
        """Close the bag (idempotent; also called on SIGINT/SIGTERM)."""
        first = not self.bag.closed
        if first:
            phases.mark("bag_close_start", self.get_name(), self.run.get("out"))
            self._keep_wall_span()
        self.bag.close()
        if first:
            phases.mark("bag_closed", self.get_name(), self.run.get("out"))

    def _keep_wall_span(self) -> None:
        """Put the wall time of the first message and the span to the last into the bag's custom data."""
        if self._wall_first_ns:
            self.bag.set_custom_data(
                {
                    WALL_START_KEY: str(self._wall_first_ns),
                    WALL_DURATION_KEY: str(self._wall_last_ns - self._wall_first_ns),
                }
            )


def main() -> int:
    return node_main(RecorderNode)


if __name__ == "__main__":
    sys.exit(main())
