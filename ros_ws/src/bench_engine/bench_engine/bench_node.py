"""ROS shell shared by every node of the bench: run config, QoS, readiness barrier, acks, clean shutdown.

Each node is built from the run config the launcher writes (``run_config.yaml``: the resolved scenario plus
the run's filters, seed and recording flag) and finds its own topics in :mod:`bench_engine.graph`. Protocol:

1. Readiness: a node creates its publishers and subscriptions, waits until each data publisher sees the
   number of subscribers the graph expects, then announces its name on ``/sim/ready`` (transient-local).
2. The pacing source (truth or player) starts once every node is ready, and paces on ``/sim/ack``.
3. The source publishes ``/sim/totals`` (every data topic's final message count) and ``/sim/done``
   (transient-local) when every consumer has caught up; the recorder closes the bag once it holds those
   counts, and each node stops once its published messages are acknowledged by their readers or they left.
"""
from __future__ import annotations

import argparse
import faulthandler
import os
import signal
import sys
import time
from typing import Callable, Iterable

import rclpy
import yaml
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String, UInt64

from bench_msgs.msg import StepAck
from bench_engine import phases
from bench_engine.config import ScenarioError
from bench_engine.cdr import deserialize, lite_class, serialize
from bench_engine.graph import ACK_TOPIC, ACK_TYPE, DONE_TOPIC, PACED_ROLES, READY_TOPIC, Graph, build_graph
from bench_engine.msg_schema import message_class
from bench_engine.process import exit_now
from bench_engine.stage import codec
from bench_engine.timegrid import build_time

DATA_QOS = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)
LATCHED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
FLUSH_TIMEOUT_S = 10.0
ACK_FLUSH_S = 0.01
ACK_POLL_S = 0.01
"""A held-back acknowledgement is sent within this wall time (``BenchNode.ack``)."""


def delivered(publishers: list, timeout_s: float = FLUSH_TIMEOUT_S) -> list:
    """Wait until each publisher's messages are acknowledged by its readers or it has no reader left; returns
    the publishers still waiting after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    pending = list(publishers)
    while pending and time.monotonic() < deadline:
        pending = [p for p in pending if p.get_subscription_count() > 0
                   and not p.wait_for_all_acked(rclpy.duration.Duration(seconds=ACK_POLL_S))]
    return pending


def load_run_config(path: str) -> dict:
    """The launcher's run config: {scenario: {...}, filters: [...], record: bool, source: str, ...}."""
    with open(path, encoding="utf-8") as f:
        run = yaml.safe_load(f)
    for key in ("scenario", "filters"):
        if key not in run:
            raise ScenarioError(f"run config {path} has no '{key}' key")
    return run


def graph_of(run: dict) -> Graph:
    return build_graph(run["scenario"], run["filters"], run.get("record", True), run.get("source", "truth"))


def stamp_to_ns(stamp) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def ns_to_stamp(t_ns: int, stamp) -> None:
    stamp.sec, stamp.nanosec = divmod(int(t_ns), 1_000_000_000)


class BenchNode(Node):
    """Base class: subclasses create their endpoints in ``setup()`` and react in callbacks."""

    def __init__(self, name: str, run: dict) -> None:
        super().__init__(name)
        self.run = run
        self.cfg = run["scenario"]
        self.graph = graph_of(run)
        self.spec = self.graph.node(name)
        self.finished = False
        self.failed = ""
        self._announced = False
        self._publishers_by_topic: dict[str, object] = {}
        self._ready_pub = self.create_publisher(String, READY_TOPIC, LATCHED_QOS)
        self._ack_pub = None
        self.published: dict[str, int] = {}
        """Data topic -> messages this node published on it (reported in its acknowledgements)."""
        if self.spec.role in PACED_ROLES:
            self._ack_pub = self.create_publisher(StepAck, ACK_TOPIC, DATA_QOS)
            self._setup_acks()
        if self.spec.role not in ("source", "replay"):
            self.create_subscription(UInt64, DONE_TOPIC, self._on_done, LATCHED_QOS)
        self.setup()
        self._ready_timer = self.create_timer(0.02, self._check_ready)

    # -- for subclasses -------------------------------------------------------------------------------
    def setup(self) -> None:
        """Create publishers/subscriptions (use ``data_publisher`` for data topics)."""

    def on_done(self, last_step: int) -> None:
        """The run is complete; default: flush publishers and stop."""
        self.flush_and_finish()

    def on_ready(self) -> None:
        """Called once, after this node announced itself ready."""

    def data_publisher(self, msg_type, topic: str):
        pub = self.create_publisher(msg_type, topic, DATA_QOS)
        self._publishers_by_topic[topic] = pub
        self.published[topic] = 0
        return pub

    def publish_data(self, topic: str, msg) -> None:
        """Publish on a data topic, counting the message for the pacing acknowledgements."""
        self._publishers_by_topic[topic].publish(msg)
        self.published[topic] += 1

    def data_subscription(self, msg_type, topic: str, callback: Callable, raw: bool = False):
        return self.create_subscription(msg_type, topic, callback, DATA_QOS, raw=raw)

    def item_publisher(self, topic: str, type_name: str) -> Callable[[object], None]:
        """A data publisher on ``topic`` that takes the cores' items: each is encoded by the codec registered
        for ``type_name`` into a light message and sent as CDR bytes (bench_engine.cdr)."""
        self.data_publisher(message_class(type_name), topic)
        encode, lite = codec(type_name).encode, lite_class(type_name)
        return lambda item: self.publish_data(topic, serialize(type_name, encode(item, lite)))

    def item_subscription(self, topic: str, type_name: str, callback: Callable[[object], None]) -> None:
        """A data subscription on ``topic`` that hands ``callback`` the light message read from the CDR bytes
        (bench_engine.cdr)."""
        self.data_subscription(message_class(type_name), topic,
                               lambda data: callback(deserialize(type_name, data)), raw=True)

    def ack(self, step: int, count: int) -> None:
        """Acknowledge step ``step`` with the node's cumulative consumed message ``count`` and its published
        counts per topic (bench_engine.lockstep).

        With a pacing window W > 0 an acknowledgement is sent once the step or the count has advanced by
        max(1, W // 4) since the last one sent, and otherwise within ACK_FLUSH_S by a timer: the source
        never waits on a held-back one for long, and the graph carries a quarter of the ack traffic."""
        if self._ack_every == 1 or (step - self._ack_sent[0] >= self._ack_every
                                    or count - self._ack_sent[1] >= self._ack_every):
            self._send_ack(step, count)
        else:
            self._ack_unsent = (step, count)

    def _setup_acks(self) -> None:
        window = build_time(self.cfg).pacing_window
        self._ack_every = max(1, window // 4)
        self._ack_sent: tuple[int, int] = (-1, 0)
        self._ack_unsent: tuple[int, int] | None = None
        self._ack_msg = lite_class(ACK_TYPE)()
        self._ack_msg.node = self.get_name()
        self._ack_msg.topics = sorted(self.spec.publishes)
        if self._ack_every > 1:
            self.create_timer(ACK_FLUSH_S, self._flush_ack)

    def _flush_ack(self) -> None:
        if self._ack_unsent is not None:
            self._send_ack(*self._ack_unsent)

    def _send_ack(self, step: int, count: int) -> None:
        self._ack_msg.step, self._ack_msg.count = int(step), int(count)
        self._ack_msg.published = [self.published.get(t, 0) for t in self._ack_msg.topics]
        self._ack_pub.publish(serialize(ACK_TYPE, self._ack_msg))
        self._ack_sent, self._ack_unsent = (int(step), int(count)), None

    def fail(self, message: str) -> None:
        """Stop this node with an error (reported by the launcher)."""
        self.get_logger().error(message)
        self.failed = message
        self.finished = True

    def flush_and_finish(self) -> None:
        """Stop once every data message this node published is acknowledged by its readers, or its readers
        have left (after /sim/done only the recorder still reads, and it leaves once it holds every message).
        Acknowledgements need no flush: the source had them all before it sent /sim/done."""
        for pub in delivered(list(self._publishers_by_topic.values())):
            self.get_logger().warning(f"{pub.topic_name}: not every message was acknowledged in time")
        self.finished = True

    # -- readiness ------------------------------------------------------------------------------------
    def _expected_matches(self) -> Iterable[tuple[object, int]]:
        for topic, pub in self._publishers_by_topic.items():
            yield pub, self.graph.expected_subscribers(topic)
        if self._ack_pub is not None:
            yield self._ack_pub, 1

    def _check_ready(self) -> None:
        if self._announced:
            return
        if all(pub.get_subscription_count() >= n for pub, n in self._expected_matches()):
            self._announced = True
            self._ready_timer.cancel()
            self._ready_pub.publish(String(data=self.get_name()))
            phases.mark("ready", self.get_name(), self.run.get("out"))
            self.on_ready()

    def _on_done(self, msg: UInt64) -> None:
        if not self.finished:
            phases.mark("done_received", self.get_name(), self.run.get("out"))
            self.on_done(int(msg.data))


def make_executor(kind: str):
    """``events`` (rclpy's EventsExecutor, fastest) or ``single`` (SingleThreadedExecutor)."""
    if kind == "events":
        from rclpy.experimental import EventsExecutor
        return EventsExecutor()
    if kind == "single":
        return rclpy.executors.SingleThreadedExecutor()
    raise ScenarioError(f"executor must be 'events' or 'single', got {kind!r}")


class _StopFlag:
    def __init__(self) -> None:
        self.signal = 0

    def __call__(self, signum, _frame) -> None:
        self.signal = signum


ORPHAN_EXIT_S = 10.0
"""How long an orphaned node process (its launcher killed) may take to close its nodes and exit."""


def spin_nodes(nodes: list[BenchNode], executor_kind: str = "events", parent_pid: int | None = None,
               shutdown_executor: bool = True) -> int:
    """Spin until every node finished, SIGINT/SIGTERM, or (when ``parent_pid`` is given) the parent process
    went away; close nodes; return an exit code. ``shutdown_executor=False`` leaves the executor to the end of
    the process: a node process exits right after, and rclpy's EventsExecutor was seen spinning for good in
    its shutdown once (a node process that never exited)."""
    stop = _StopFlag()
    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    executor = make_executor(executor_kind)
    names = {id(node): node.get_name() for node in nodes}
    for node in nodes:
        executor.add_node(node)
    next_parent_check = time.monotonic() + 1.0
    try:
        while not stop.signal and not all(n.finished for n in nodes):
            executor.spin_once(timeout_sec=0.05)
            if parent_pid is not None and time.monotonic() > next_parent_check:
                next_parent_check = time.monotonic() + 1.0
                if os.getppid() != parent_pid:  # orphaned: the launcher was killed
                    for node in nodes:
                        node.failed = node.failed or "the launcher went away; stopping"
                    # Nobody will stop this process should rclpy's teardown hang (seen once: the
                    # EventsExecutor's destructor spinning in EventHandler.__exit__ with the GIL held): the
                    # nodes close (the bag first), then faulthandler's own thread ends the process regardless.
                    faulthandler.dump_traceback_later(ORPHAN_EXIT_S, exit=True)
                    break
    except Exception as err:  # a callback raised (rclpy logged which node): stop cleanly, report it
        for node in nodes:
            node.failed = node.failed or f"a callback raised {err!r}"
    finally:
        if phases.enabled():
            for node in nodes:
                phases.mark("spin_end", names[id(node)], node.run.get("out"))
        for node in nodes:
            close = getattr(node, "close", None)
            if close is not None:
                close()
            executor.remove_node(node)
            node.destroy_node()
        if shutdown_executor:
            executor.shutdown(timeout_sec=1.0)
    failed = [n for n in nodes if n.failed]
    for node in failed:
        print(f"[{names[id(node)]}] failed: {node.failed}", file=sys.stderr)
    if stop.signal:
        return 128 + stop.signal
    return 1 if failed else 0


def node_main(node_class: type[BenchNode], argv: list[str] | None = None) -> int:
    """Entry point of a node process: ``python -m MODULE --name NAME --config RUN_CONFIG [--ros-args ...]``;
    exits the process when the node is done."""
    imported = time.time()
    argv = sys.argv[1:] if argv is None else argv
    ros_args = argv[argv.index("--ros-args"):] if "--ros-args" in argv else []
    own = argv[: len(argv) - len(ros_args)]
    parser = argparse.ArgumentParser(description=node_class.__doc__)
    parser.add_argument("--name", required=True, help="node name (as in the run's graph)")
    parser.add_argument("--config", required=True, help="run_config.yaml written by the launcher")
    parser.add_argument("--executor", default="events", choices=["events", "single"])
    args = parser.parse_args(own)
    rclpy.init(args=["node"] + ros_args, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    initialised = time.time()
    try:
        run = load_run_config(args.config)
        if phases.enabled():
            phases.mark("proc_start", args.name, run.get("out"), t=phases.process_start_time())
            phases.mark("imported", args.name, run.get("out"), t=imported)
            phases.mark("rclpy_init", args.name, run.get("out"), t=initialised)
        node = node_class(args.name, run)
        phases.mark("node_created", args.name, run.get("out"))
    except (ScenarioError, KeyError, ValueError, OSError) as err:
        print(f"[{args.name}] error: {err}", file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    code = spin_nodes([node], args.executor, parent_pid=os.getppid(), shutdown_executor=False)
    rclpy.try_shutdown()
    phases.mark("exit", args.name, run.get("out"))
    exit_now(code)
