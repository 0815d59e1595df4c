"""ROS shell shared by every node of the bench: parameters, topics, QoS, readiness barrier, acks, shutdown.

Longer than 500 lines: the node class and the ways of running nodes (in process, as node processes, standalone)
share one readiness, done and shutdown protocol, which reads best in one place.

A node's core is configured by the node's ROS parameters alone (bench_engine.parameters: the part of the
scenario its kind reads, one read-only parameter per scenario key, e.g. ``filters.ukf.params.alpha``), plus the
shell's own parameters (:data:`SHELL_PARAMETERS`: its kind and the QoS of its data topics). Its data topics are
relative names (``radar/measurement``, ``ukf/estimate``), so a namespace or a remap moves them.

Two modes:

- **bench** (the launcher starts it with ``--name NAME --config run_config.yaml``): the run config carries the
  whole scenario, from which the node finds the run's graph (bench_engine.graph) for the lock-step protocol
  below; its parameters come from the launcher's ``params/NAME.yaml``.
- **standalone** (no run config: ``filter_node --ros-args --params-file ukf.yaml -r __node:=ukf``): the node
  builds the graph of its own parameters to learn its topics and their types, and reacts to whatever arrives,
  with no pacing, readiness or end of run; Ctrl-C stops it.

Lock-step protocol (bench mode):

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
from collections.abc import Callable, Iterable
from pathlib import Path

import rclpy
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String, UInt64

from bench_engine import phases, shm, yamlio
from bench_engine.cdr import lite_class, serialize
from bench_engine.config import ScenarioError
from bench_engine.dds_profile import use_bench_profile
from bench_engine.graph import ACK_TOPIC, ACK_TYPE, DONE_TOPIC, PACED_ROLES, READY_TOPIC, Graph, build_graph, node_kinds
from bench_engine.msg_schema import message_class
from bench_engine.parameters import description, unflatten
from bench_engine.process import exit_now, keep_until_exit
from bench_engine.scenario import upgrade_run_config
from bench_engine.stage import codec
from bench_engine.timegrid import build_time
from bench_msgs.msg import StepAck

DATA_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE
)
LATCHED_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
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
        pending = [
            p
            for p in pending
            if p.get_subscription_count() > 0 and not p.wait_for_all_acked(rclpy.duration.Duration(seconds=ACK_POLL_S))
        ]
    return pending


def load_run_config(path: str) -> dict:
    """The launcher's run config: {scenario: {...}, estimators: [...], record: bool, source: str, ...}."""
    with open(path, encoding="utf-8") as f:
        run = upgrade_run_config(yamlio.load(f))
    for key in ("scenario", "estimators"):
        if key not in run:
            raise ScenarioError(f"run config {path} has no '{key}' key")
    return run


def graph_of(run: dict) -> Graph:
    return build_graph(run["scenario"], run["estimators"], run.get("record", True), run.get("source", "truth"))


def standalone_graph(settings: dict, name: str, kind: str) -> Graph:
    """The graph a standalone node's own parameters describe (no recorder): it gives the node its topics and
    their types. An estimator kind's node is the one estimator requested."""
    kinds = node_kinds()
    if kind not in kinds:
        raise ScenarioError(
            f"parameter 'kind' must name a registered node kind, got {kind!r}; registered: {sorted(kinds)}"
        )
    graph = build_graph(settings, [name] if kinds[kind].role == "estimator" else None, record=False)
    spec = graph.node(name) if name in [n.name for n in graph.nodes] else None
    if spec is None or spec.kind != kind:
        raise ScenarioError(
            f"the parameters describe no {kind} node named '{name}' (the node's name is its name "
            f"in the scenario: rename it with -r __node:=NAME, or check the parameters file)"
        )
    return graph


def ns_to_stamp(t_ns: int, stamp) -> None:
    stamp.sec, stamp.nanosec = divmod(int(t_ns), 1_000_000_000)


SHELL_PARAMETERS = {
    "kind": (
        "",
        "the node kind whose core this node runs (bench_engine.graph.NodeKind, e.g. filter, "
        "sensor); set by the launcher or the console script",
    ),
    "qos.reliability": (
        "reliable",
        "QoS reliability of the data topics: reliable or best_effort (a best-effort "
        "subscription also hears reliable publishers)",
    ),
    "qos.history": ("keep_all", "QoS history of the data topics: keep_all or keep_last"),
    "qos.depth": (100, "QoS depth of the data topics with keep_last history"),
}
"""The shell's own parameters (name -> (default, description)); every other parameter is a scenario key."""
ROS_OWN_PARAMETERS = ("use_sim_time", "start_type_description_service")
"""Parameters rclpy declares on every node."""


def relative(topic: str) -> str:
    """A graph topic (``/radar/measurement``) as the relative name a node uses, so namespaces and remaps apply."""
    return topic.lstrip("/")


def data_qos(reliability: str, history: str, depth: int) -> QoSProfile:
    """The QoS of a node's data topics (bench mode: reliable, keep-all, as the lock-step pacing needs)."""
    reliabilities = {"reliable": ReliabilityPolicy.RELIABLE, "best_effort": ReliabilityPolicy.BEST_EFFORT}
    histories = {"keep_all": HistoryPolicy.KEEP_ALL, "keep_last": HistoryPolicy.KEEP_LAST}
    if reliability not in reliabilities:
        raise ScenarioError(f"parameter 'qos.reliability' must be one of {sorted(reliabilities)}, got {reliability!r}")
    if history not in histories:
        raise ScenarioError(f"parameter 'qos.history' must be one of {sorted(histories)}, got {history!r}")
    if not isinstance(depth, int) or depth < 1:
        raise ScenarioError(f"parameter 'qos.depth' must be an integer >= 1, got {depth!r}")
    return QoSProfile(
        history=histories[history],
        depth=depth,
        reliability=reliabilities[reliability],
        durability=DurabilityPolicy.VOLATILE,
    )


class BenchNode(Node):
    """Base class: subclasses create their endpoints in ``setup()`` and react in callbacks.

    ``run``: the launcher's run config (bench mode), or None (standalone). ``parameters``: parameter values
    given in code (the single-process launcher), besides those of ``--params-file``. ``kind``: the default of
    the ``kind`` parameter (a standalone console script's kind). ``context``: rclpy's (default: the global one)."""

    def __init__(
        self, name: str, run: dict | None, parameters: dict | None = None, kind: str = "", context=None
    ) -> None:
        overrides = [Parameter(k, value=v) for k, v in (parameters or {}).items()]
        super().__init__(name, parameter_overrides=overrides, context=context)
        self.settings, shell = self._declare_parameters(kind)
        """The scenario part this node's core reads: its parameters (bench_engine.parameters)."""
        self.qos = data_qos(shell["qos.reliability"], shell["qos.history"], shell["qos.depth"])
        self.run = run
        self.standalone = run is None
        if self.standalone:
            self.cfg = self.settings
            self.graph = standalone_graph(self.settings, self.get_name(), shell["kind"])
        else:
            self.cfg = run["scenario"]
            self.graph = graph_of(run)
        self.spec = self.graph.node(self.get_name())
        self.finished = False
        self.failed = ""
        self._announced = False
        self._publishers_by_topic: dict[str, object] = {}
        self._ack_pub = None
        self.published: dict[str, int] = {}
        """Data topic -> messages this node published on it (reported in its acknowledgements)."""
        if not self.standalone:
            self._ready_pub = self.create_publisher(String, READY_TOPIC, LATCHED_QOS)
            if self.spec.role in PACED_ROLES:
                self._ack_pub = self.create_publisher(StepAck, ACK_TOPIC, DATA_QOS)
                self._setup_acks()
            if self.spec.role not in ("source", "replay"):
                self.create_subscription(UInt64, DONE_TOPIC, self._on_done, LATCHED_QOS)
        self.setup()
        if not self.standalone:
            self._ready_timer = self.create_timer(0.02, self._check_ready)

    def _declare_parameters(self, kind: str) -> tuple[dict, dict]:
        """Declare every parameter read-only: the shell's (SHELL_PARAMETERS, with their defaults) and every
        scenario key given (params file or constructor); returns (scenario settings, shell values)."""
        given = {
            name: p.value
            for name, p in self._parameter_overrides.items()  # rclpy's merged overrides
            if name not in ROS_OWN_PARAMETERS
        }
        shell_defaults = {**{k: v for k, (v, _) in SHELL_PARAMETERS.items()}, "kind": kind}
        declared = self.declare_parameters(
            "",
            [
                *(
                    (name, default, ParameterDescriptor(description=SHELL_PARAMETERS[name][1], read_only=True))
                    for name, default in shell_defaults.items()
                ),
                *(
                    (name, value, ParameterDescriptor(description=description(name), read_only=True))
                    for name, value in sorted(given.items())
                    if name not in SHELL_PARAMETERS
                ),
            ],
        )
        values = {p.name: p.value for p in declared}
        shell = {name: values[name] for name in SHELL_PARAMETERS}
        return unflatten({k: v for k, v in values.items() if k not in SHELL_PARAMETERS}), shell

    # -- for subclasses -------------------------------------------------------------------------------
    def setup(self) -> None:
        """Create publishers/subscriptions (use ``data_publisher`` for data topics)."""

    def on_done(self, last_step: int) -> None:
        """The run is complete; default: flush publishers and stop."""
        self.flush_and_finish()

    def on_ready(self) -> None:
        """Called once, after this node announced itself ready."""

    def data_publisher(self, msg_type, topic: str):
        """A publisher on the graph's data topic ``topic`` (by its relative name), with the node's data QoS."""
        pub = self.create_publisher(msg_type, relative(topic), self.qos)
        self._publishers_by_topic[topic] = pub
        self.published[topic] = 0
        return pub

    def publish_data(self, topic: str, msg) -> None:
        """Publish on a data topic, counting the message for the pacing acknowledgements."""
        self._publishers_by_topic[topic].publish(msg)
        self.published[topic] += 1

    def data_subscription(self, msg_type, topic: str, callback: Callable, raw: bool = False):
        return self.create_subscription(msg_type, relative(topic), callback, self.qos, raw=raw)

    def item_publisher(self, topic: str, type_name: str) -> Callable[[object], None]:
        """A data publisher on ``topic`` that takes the cores' items: each is encoded by the codec registered
        for ``type_name`` into a light message and sent as CDR bytes (bench_engine.cdr)."""
        self.data_publisher(message_class(type_name), topic)
        encode, lite = codec(type_name).encode, lite_class(type_name)
        return lambda item: self.publish_data(topic, serialize(type_name, encode(item, lite)))

    def ack(self, step: int, count: int) -> None:
        """Acknowledge step ``step`` with the node's cumulative consumed message ``count`` and its published
        counts per topic (bench_engine.lockstep).

        With a pacing window W > 0 an acknowledgement is sent once the step or the count has advanced by a
        quarter of the node's own window (W times its pacing weight: the recorder's spans every topic it
        records) since the last one sent, and otherwise within ACK_FLUSH_S by a timer: the source never waits
        on a held-back one for long, and the graph carries a quarter of the ack traffic."""
        if self._ack_every == 1 or (
            step - self._ack_sent[0] >= self._ack_every or count - self._ack_sent[1] >= self._ack_every
        ):
            self._send_ack(step, count)
        else:
            self._ack_unsent = (step, count)

    def _setup_acks(self) -> None:
        window = build_time(self.cfg).pacing_window * self.graph.pacing_weights().get(self.get_name(), 1)
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

TEARDOWN_S = 30.0
"""How long rclpy's teardown of the nodes (destroy_node, the executor's shutdown) may take once every node is
closed (its bag and files written) before the process ends anyway, with the hanging threads' tracebacks on stderr
and exit code 1. Seen under load: Fast DDS's destroy_participant spinning for good (rmw_destroy_node ->
DomainParticipant::set_listener). Only where the nodes are torn down: a node process (the launcher would stop it
after LINGER_S) and a standalone node; a single-process run tears nothing down (``teardown=False``)."""


def spin_in_process(
    domain_id: int,
    make_nodes: Callable[[], list[BenchNode]],
    executor_kind: str = "events",
    on_exit: Callable[[], None] = lambda: None,
) -> int:
    """rclpy initialised on ``domain_id`` (no signal handlers: :func:`spin_nodes` installs its own), the nodes
    ``make_nodes`` creates spun in this process until they finish and closed, ``on_exit`` called; an exit code,
    the run's. Nothing of ROS is torn down, and the caller ends the process with exit_now (a single-process run).

    Why: once its nodes are closed (the bag complete and closed, timing.json written) all a run's process still
    does is score the bag (launch.py) and exit, and none of that needs DDS; the teardown, on the other hand, may
    spin for good (Fast DDS's destroy_participant, seen under load), and nothing outside would stop this process.
    So no teardown stands between the run's end and the process's: the nodes and the executor are kept
    (spin_nodes with ``teardown=False``), rclpy is not shut down, and exit_now ends the process with none of their
    destructors run. The one thing the teardown did that outlives the process, removing the participant's files
    in /dev/shm, is done here (bench_engine.shm.release_own); its peers, all in this process, need no goodbye."""
    use_bench_profile()
    rclpy.init(domain_id=domain_id, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    try:
        code = spin_nodes(make_nodes(), executor_kind, teardown=False)
        on_exit()
        return code
    finally:
        shm.release_own()


def spin_nodes(
    nodes: list[BenchNode],
    executor_kind: str = "events",
    parent_pid: int | None = None,
    shutdown_executor: bool = True,
    teardown: bool = True,
) -> int:
    """Spin until every node finished, SIGINT/SIGTERM, or (when ``parent_pid`` is given) the parent process
    went away; close nodes; return an exit code. ``shutdown_executor=False`` leaves the executor to the end of
    the process: a node process exits right after, and rclpy's EventsExecutor was seen spinning for good in
    its shutdown once (a node process that never exited).

    ``teardown=False`` destroys nothing: once closed, the nodes and the executor are handed to
    bench_engine.process.keep_until_exit (a single-process run: :func:`spin_in_process` says why). With the
    teardown (a node process, a standalone node) the nodes' participant says goodbye to its peers in other
    processes, whose publishers then stop waiting for its acknowledgements."""
    stop = _StopFlag()
    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    executor = make_executor(executor_kind)
    names = {id(node): node.get_name() for node in nodes}
    for node in nodes:
        executor.add_node(node)
    next_parent_check = time.monotonic() + 1.0
    orphaned = False
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
                    orphaned = True
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
        if teardown:
            _tear_down(executor, nodes, shutdown_executor, deadline=not orphaned)
        else:
            keep_until_exit(executor, *nodes)
    failed = [n for n in nodes if n.failed]
    for node in failed:
        print(f"[{names[id(node)]}] failed: {node.failed}", file=sys.stderr)
    if stop.signal:
        return 128 + stop.signal
    return 1 if failed else 0


def _tear_down(executor, nodes: list[BenchNode], shutdown_executor: bool, deadline: bool) -> None:
    """Destroy the nodes (and shut the executor down), within TEARDOWN_S when ``deadline`` (an orphaned node
    process has its own deadline running already)."""
    if deadline:
        faulthandler.dump_traceback_later(TEARDOWN_S, exit=True)
    try:
        for node in nodes:
            executor.remove_node(node)
            node.destroy_node()
        if shutdown_executor:
            executor.shutdown(timeout_sec=1.0)
    finally:
        if deadline:
            faulthandler.cancel_dump_traceback_later()


def split_ros_args(argv: list[str]) -> tuple[list[str], list[str]]:
    """(the node's own arguments, ``--ros-args …`` onwards)."""
    ros_args = argv[argv.index("--ros-args") :] if "--ros-args" in argv else []
    return argv[: len(argv) - len(ros_args)], ros_args


def node_main(node_class: type[BenchNode], argv: list[str] | None = None) -> int:
    """Entry point of a bench node process: ``python -m MODULE --name NAME --config RUN_CONFIG --ros-args
    --params-file params/NAME.yaml``; exits the process when the node is done."""
    imported = time.time()
    own, ros_args = split_ros_args(sys.argv[1:] if argv is None else argv)
    parser = argparse.ArgumentParser(description=node_class.__doc__)
    parser.add_argument("--name", required=True, help="node name (as in the run's graph)")
    parser.add_argument("--config", required=True, help="run_config.yaml written by the launcher")
    parser.add_argument("--executor", default="events", choices=["events", "single"])
    args = parser.parse_args(own)
    use_bench_profile()
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


STANDALONE_HELP = """Runs one bench {kind} node in any ROS 2 graph, without the bench's launcher or lock-step pacing.

Every setting is a ROS parameter named after its scenario key (e.g. filters.ukf.type, filters.ukf.params.alpha,
sensors.radar.station.lat_deg); the node's name is its name in the scenario. The easiest parameters file is
the one the launcher writes for each node of a run: OUT/params/NAME.yaml. Shell parameters: kind,
qos.reliability (reliable | best_effort), qos.history (keep_all | keep_last), qos.depth. Topics are relative
names (radar/measurement, ukf/estimate): remap them with -r FROM:=TO.

Example:
  {command} --ros-args -r __node:=ukf --params-file runs/x/params/ukf.yaml \\
      -p qos.reliability:=best_effort -r radar/measurement:=/my_radar/measurement

Exit code: 0 after Ctrl-C or SIGTERM, 2 for a bad or missing parameter (named on one line)."""


def standalone_main(node_class: type[BenchNode], kind: str, argv: list[str] | None = None) -> int:
    """Entry point of a standalone node (console scripts ``filter_node``, ``sensor_node``): parameters and
    remaps from ``--ros-args``; runs until SIGINT/SIGTERM."""
    own, ros_args = split_ros_args(sys.argv[1:] if argv is None else argv)
    command = Path(sys.argv[0]).name
    parser = argparse.ArgumentParser(
        prog=command,
        description=STANDALONE_HELP.format(kind=kind, command=command),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--executor", default="events", choices=["events", "single"])
    args = parser.parse_args(own)
    rclpy.init(args=[command] + ros_args, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    try:
        node = node_class(kind, None, kind=kind)
    except (ScenarioError, KeyError, ValueError, OSError) as err:
        print(f"[{command}] error: {err}", file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    code = spin_nodes([node], args.executor)
    rclpy.try_shutdown()
    return 0 if code >= 128 else code
