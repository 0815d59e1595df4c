"""Start a run's node graph (one process per node, or all in one process), supervise it, keep the bag whole.

Everything is validated before anything starts: the scenario's top-level keys, every registered section and
every node's core objects are built once in the launcher, so a bad key stops the run with a message naming it.
"""

from __future__ import annotations

import importlib
import os
import signal
import subprocess
import sys
import threading
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path

import setproctitle

from bench_engine import phases, yamlio
from bench_engine.bag_errors import BagUnrecoverable
from bench_engine.config import ScenarioError, apply_overrides, load_scenario, select_variant
from bench_engine.domains import DomainInUse, Reservation, reserve
from bench_engine.graph import Graph, build_graph, node_kinds, resolve_estimators
from bench_engine.parameters import node_parameters, node_settings, parameters_file
from bench_engine.process import exit_now, keep_until_exit
from bench_engine.recovery import ensure_complete
from bench_engine.scenario import check_top_level, coerce_scenario, scenario_seed, section_readers

MAX_DOMAIN_ID = 101


@dataclass
class RunPlan:
    out: Path
    run: dict
    graph: Graph
    config_path: Path
    logs: Path = field(init=False)

    def __post_init__(self) -> None:
        self.logs = self.out / "logs"

    @property
    def bag_dir(self) -> Path:
        return Path(self.run["bag_dir"])

    def parameters_file(self, name: str) -> Path:
        """Node ``name``'s ROS parameters (``--params-file``), written by :func:`prepare_run`."""
        return self.out / "params" / f"{name}.yaml"

    def node_argv(self, name: str) -> list[str]:
        """A node process's arguments after ``python -m MODULE``."""
        return [
            "--name",
            name,
            "--config",
            str(self.config_path),
            "--ros-args",
            "--params-file",
            str(self.parameters_file(name)),
        ]


def local_dds_env(domain_id: int) -> dict[str, str]:
    """Environment for DDS on this host only, on its own domain."""
    if not 0 <= domain_id <= MAX_DOMAIN_ID:
        raise ScenarioError(f"ROS domain id must be in [0, {MAX_DOMAIN_ID}], got {domain_id}")
    env = dict(os.environ)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["ROS_DOMAIN_ID"] = str(domain_id)
    # One BLAS thread per process: the graph's processes already share the cores, and threaded BLAS on
    # 6x6 matrices costs milliseconds per call under load.
    env["OPENBLAS_NUM_THREADS"] = "1"
    return env


def validate(cfg: dict, estimators: list[str], source: str) -> None:
    """Build every object of the run once; raises ScenarioError naming the first bad key or value.

    Checks the top-level keys and the time grid (bench_engine.scenario), every registered section
    (``tracking_bench.sections``: a reader cfg -> typed section) and each node's core objects (its kind's
    ``check``)."""
    check_top_level(cfg)
    for read in section_readers().values():
        read(cfg)
    kinds = node_kinds()
    for spec in build_graph(cfg, estimators, record=False, source=source).nodes:
        settings = node_settings(cfg, spec.kind, spec.name)
        check = kinds[spec.kind].check
        if check is not None:
            check(settings, spec.name)


def write_parameters(plan: RunPlan) -> None:
    """One ``ros__parameters`` file per node: its kind and its settings (bench_engine.parameters)."""
    cfg = plan.run["scenario"]
    plan.parameters_file("x").parent.mkdir(exist_ok=True)
    for spec in plan.graph.nodes:
        flat = {"kind": spec.kind, **node_parameters(cfg, spec.kind, spec.name)}
        plan.parameters_file(spec.name).write_text(parameters_file(flat))


def resolve_run(
    scenario: str,
    estimators: list[str] | None = None,
    seed: int | None = None,
    overrides: list[str] = (),
    variant: str | None = None,
    source: str = "truth",
    cfg: dict | None = None,
) -> tuple[dict, list[str]]:
    """The validated scenario of a run (``cfg``, else ``scenario`` with its ``variant`` and ``overrides``; the
    ``seed`` set; bench_engine.scenario.coerce_scenario) and its estimators; every object of the run is built
    once (:func:`validate`), so raises ScenarioError naming the first bad key or value."""
    if cfg is None:
        cfg = apply_overrides(select_variant(load_scenario(scenario), variant), overrides)
    if seed is not None:
        cfg = {**cfg, "seed": int(seed)}
    names = resolve_estimators(cfg, estimators)
    validate(cfg, names, source)
    return coerce_scenario(cfg), names


def prepare_run(
    scenario: str,
    out: Path,
    estimators: list[str] | None = None,
    seed: int | None = None,
    overrides: list[str] = (),
    variant: str | None = None,
    record: bool = True,
    source: str = "truth",
    extra: dict | None = None,
    cfg: dict | None = None,
) -> RunPlan:
    """Resolve and validate the scenario, build the graph and write ``run_config.yaml`` into ``out``: the
    scenario as validated (every value of its declared type, deprecated keys renamed:
    bench_engine.scenario.coerce_scenario), the selected ``estimators``, the seed and the run's options."""
    cfg, names = resolve_run(scenario, estimators, seed, overrides, variant, source, cfg)
    graph = build_graph(cfg, names, record, source)
    out = Path(out).resolve()
    if record and (out / "bag").exists():
        raise ScenarioError(f"{out / 'bag'} already exists: choose another output directory or remove it")
    out.mkdir(parents=True, exist_ok=True)
    run = {
        "scenario": cfg,
        "estimators": names,
        "record": record,
        "source": source,
        "out": str(out),
        "bag_dir": str(out / "bag"),
        "seed": scenario_seed(cfg),
    }
    run.update(extra or {})
    config_path = out / "run_config.yaml"
    config_path.write_text(yamlio.dump(run, sort_keys=False))
    plan = RunPlan(out, run, graph, config_path)
    write_parameters(plan)
    return plan


class ForkedNode:
    """A node process forked from the launcher, with the part of subprocess.Popen's interface the supervisor
    uses (poll, wait, send_signal, kill, returncode)."""

    def __init__(self, pid: int) -> None:
        self.pid = pid
        self.returncode: int | None = None

    def poll(self) -> int | None:
        if self.returncode is None:
            pid, status = os.waitpid(self.pid, os.WNOHANG)
            if pid:
                self.returncode = os.waitstatus_to_exitcode(status)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        deadline = None if timeout is None else time.monotonic() + timeout
        while self.poll() is None:
            if deadline is not None and time.monotonic() > deadline:
                raise subprocess.TimeoutExpired(f"node process {self.pid}", timeout)
            time.sleep(0.01)
        return self.returncode

    def send_signal(self, signum: int) -> None:
        if self.poll() is None:
            os.kill(self.pid, signum)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)


NO_FORK_ENV = "TRACKING_BENCH_NO_FORK"
"""Set to 1 to start every node and every Monte Carlo run as a fresh interpreter instead of forking it."""


def can_fork() -> bool:
    """Whether processes may be forked from this one: fork exists, no Python thread but this one, rclpy never
    initialised here (its DDS threads), and NO_FORK_ENV unset. (The only native threads then are LTTng-UST's
    two idle listener threads, started when rclpy's tracing library loads; a child has none of them.)"""
    if not hasattr(os, "fork") or os.environ.get(NO_FORK_ENV) == "1" or threading.active_count() != 1:
        return False
    rclpy = sys.modules.get("rclpy")
    return rclpy is None or not rclpy.ok()


def fork_node(module: str, argv: list[str], env: dict[str, str], log: Path) -> ForkedNode:
    """Start node ``name`` (``python -m module`` equivalent) as a child forked from this process, which has
    already imported the node's module: the child skips the interpreter start and the imports (numpy, scipy,
    rclpy, the cores' modules), which dominate a node process's start-up, and inherits what validation built
    (the truth's trajectory). Its own session, environment and log, as with
    subprocess.Popen(start_new_session=True), and the command line a fresh node process would have (``ps``,
    ``pgrep -f "--name NODE --config …"`` find it the same way)."""
    node_module = importlib.import_module(module)
    sys.stdout.flush()
    sys.stderr.flush()
    pid = os.fork()
    if pid:
        return ForkedNode(pid)
    code = 1
    try:  # the child: never returns into the launcher's code
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        os.setsid()
        fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        os.dup2(fd, 1)
        os.dup2(fd, 2)
        os.close(fd)
        sys.argv = [module, *argv]
        setproctitle.setproctitle(" ".join([sys.executable, "-m", *sys.argv]))  # before environ changes
        os.environ.clear()
        os.environ.update(env)
        code = node_module.main()
    except SystemExit as exit_:
        code = exit_.code if isinstance(exit_.code, int) else 1
    except BaseException:  # noqa: B036 - report anything, then leave the child
        traceback.print_exc()
    finally:
        exit_now(code)


def run_multiprocess(
    plan: RunPlan, domain_id: int, timeout_s: float = 3600.0, quiet: bool = False, fork: bool = True
) -> int:
    """One process per node, forked from this one when it can (``fork_node``: the fast start-up), else or
    without ``fork`` each a fresh interpreter; returns 0 on success, non-zero (naming the failed node)
    otherwise."""
    env = local_dds_env(domain_id)
    plan.logs.mkdir(exist_ok=True)
    procs: dict[str, subprocess.Popen | ForkedNode] = {}
    interrupted = []

    def forward(signum, _frame):
        interrupted.append(signum)

    fork = fork and can_fork()
    if fork:
        # Import every node module first (the shells compile the messages' CDR code on import), so the nodes
        # are forked back to back: a participant that starts well before the others has sent its initial DDS
        # announcements by the time they start, and discovering it then waits for its next periodic one
        # (scripts/bench_phases.py shows a run's start-up).
        _importable([spec.node.split(":")[0] for spec in plan.graph.nodes])
    previous = {s: signal.signal(s, forward) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        for spec in plan.graph.start_order():
            module, log_path = spec.node.split(":")[0], plan.logs / f"{spec.name}.log"
            if fork:
                try:
                    procs[spec.name] = fork_node(module, plan.node_argv(spec.name), env, log_path)
                    continue
                except ImportError:  # the node's own fresh process reports it
                    pass
            log = open(log_path, "w")
            procs[spec.name] = subprocess.Popen(
                [sys.executable, "-m", module, *plan.node_argv(spec.name)],
                env=env,
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
        phases.mark("spawned", "launcher", plan.out)
        return _supervise(plan, procs, interrupted, timeout_s, quiet)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def _importable(modules: list[str]) -> None:
    """Import ``modules`` now; one that fails is left for its node's own process to report."""
    for module in dict.fromkeys(modules):
        try:
            importlib.import_module(module)
        except ImportError:
            pass


def _exit_text(code: int) -> str:
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"


LINGER_S = 5.0
"""How long nodes may take to exit once the source finished and the recorder closed the bag (a node's normal
exit takes well under a second; one stuck in Fast DDS's teardown never exits: seen several times a suite run)."""

STOP_GRACE_S = 10.0
"""How long a node may take to exit after SIGINT before it is killed (SIGKILL)."""

LINGER_GRACE_S = 2.0
"""The same for a node still up LINGER_S after the run completed: its bag is closed, and a node stuck in C code
does not run its SIGINT handler anyway."""


def _supervise(plan: RunPlan, procs: dict, interrupted: list, timeout_s: float, quiet: bool) -> int:
    """Wait for the nodes; on the first failure stop the others and name the node that died first. A bag a
    killed recorder left incomplete is rebuilt (bench_engine.recovery)."""
    deadline = time.monotonic() + timeout_s
    first: list[str] = []
    ends = [s.name for s in plan.graph.nodes if s.role in ("source", "replay", "recorder") and s.name in procs]
    lingering: list[str] = []
    complete_at = None
    while any(p.poll() is None for p in procs.values()):
        first = [n for n, p in procs.items() if p.poll() not in (None, 0)]
        if first or interrupted or time.monotonic() > deadline:
            break
        if complete_at is None and _complete(plan, procs, ends):
            complete_at = time.monotonic()
        if complete_at is not None and time.monotonic() - complete_at > LINGER_S:
            lingering = [n for n, p in procs.items() if p.poll() is None]
            break
        time.sleep(0.05)
    if first or interrupted or lingering or time.monotonic() > deadline:
        _stop_all(procs, LINGER_GRACE_S if lingering else STOP_GRACE_S)  # lingering: nothing else went wrong
    for name in lingering:
        print(
            f"[launcher] warning: node '{name}' had not exited {LINGER_S:.0f} s after the run completed (the "
            f"bag is complete); stopped it",
            file=sys.stderr,
        )
    phases.mark("nodes_exited", "launcher", plan.out)
    _recover_bag(plan)
    phases.mark("bag_checked", "launcher", plan.out)
    if interrupted:
        print(f"[launcher] interrupted; bag closed at {plan.bag_dir}", file=sys.stderr)
        return 128 + interrupted[0]
    if time.monotonic() > deadline:
        print(f"[launcher] timed out after {timeout_s:.0f} s", file=sys.stderr)
        return 124
    first = first or [n for n, p in procs.items() if p.returncode not in (0, None) and n not in lingering]
    for name in first:
        print(
            f"[launcher] node '{name}' died first ({_exit_text(procs[name].returncode)}); "
            f"log: {plan.logs / (name + '.log')}",
            file=sys.stderr,
        )
        if not quiet:
            tail = (plan.logs / f"{name}.log").read_text(errors="replace").splitlines()[-8:]
            print("\n".join(f"    {line}" for line in tail), file=sys.stderr)
    stopped = [n for n, p in procs.items() if n not in first + lingering and p.returncode not in (0, None)]
    if first and stopped:
        print(f"[launcher] stopped after it: {', '.join(stopped)}", file=sys.stderr)
    return 1 if first else 0


def _complete(plan: RunPlan, procs: dict, ends: list[str]) -> bool:
    """The run is complete once its bag is closed (``metadata.yaml`` is written when the recorder closes it, which
    it does once it holds every topic's final count from the source), or, when nothing is recorded, once the
    source (or player) and recorder processes exited 0. A node that hangs in its ROS teardown after that (seen:
    the recorder spinning in Fast DDS's ``destroy_participant`` under load, its bag closed) is stopped after
    LINGER_S, as is any other node still up."""
    if plan.run.get("record", True) and (plan.bag_dir / "metadata.yaml").is_file():
        return True
    return all(procs[n].poll() == 0 for n in ends)


def _recover_bag(plan: RunPlan) -> None:
    if not plan.run.get("record", True):
        return
    try:
        done = ensure_complete(plan.bag_dir)
    except BagUnrecoverable as err:
        print(f"[launcher] the bag could not be recovered: {err}", file=sys.stderr)
        return
    if done is not None:
        print(f"[launcher] {done.summary()}", file=sys.stderr)


def _stop_all(procs: dict, grace_s: float = STOP_GRACE_S) -> None:
    """SIGINT every node except the recorder, then the recorder (it closes the bag), SIGKILL after ``grace_s``."""
    others = [p for n, p in procs.items() if n != "recorder"]
    for group in (others, [procs["recorder"]] if "recorder" in procs else []):
        for p in group:
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        for p in group:
            try:
                p.wait(timeout=grace_s)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


def run_graph(
    plan: RunPlan,
    domain_id: int | None,
    single_process: bool,
    executor: str = "events",
    tag: str = "launch",
    pin: bool = True,
    fork_nodes: bool = True,
) -> int:
    """Reserve a ROS domain (the given one, or the first free one), run the graph on it, release it (a
    single-process run's at the process's end: run_single_process)."""
    try:
        reservation = reserve(domain_id)
    except DomainInUse as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(
        f"[{tag}] {plan.run['scenario'].get('scenario')}: nodes {[n.name for n in plan.graph.nodes]}, "
        f"ROS_DOMAIN_ID={reservation.domain}, out {plan.out}",
        file=sys.stderr,
    )
    if single_process:  # its DDS participant outlives the run, and so does the domain's reservation
        return run_single_process(plan, reservation, executor, pin)
    try:
        return run_multiprocess(plan, reservation.domain, fork=fork_nodes)
    finally:
        reservation.release()


def node_class(node: str) -> type:
    """The class a NodeSpec names as ``module:Class``."""
    module, name = node.split(":")
    return getattr(importlib.import_module(module), name)


def _file_parameters(plan: RunPlan, name: str) -> dict:
    """The parameters :func:`write_parameters` wrote for node ``name`` (nodes in one process share rclpy's
    global arguments, so each takes its own file's values in code)."""
    return next(iter(yamlio.load(plan.parameters_file(name).read_text()).values()))["ros__parameters"]


def pin_to_one_cpu(domain_id: int) -> int | None:
    """Restrict this thread, and every thread it starts from now on, to one of the CPUs it may use; parallel
    runs (distinct domains) get different CPUs. Returns the CPU, or None when there is only one.

    Why: in one process the Python callbacks run one at a time, and spreading the DDS delivery threads over
    other cores only adds cross-core wake-ups (scripts/bench_graph.py measures both)."""
    cpus = sorted(os.sched_getaffinity(0))
    if len(cpus) < 2:
        return None
    cpu = cpus[domain_id % len(cpus)]
    os.sched_setaffinity(0, {cpu})
    return cpu


def run_single_process(plan: RunPlan, reservation: Reservation, executor: str = "events", pin: bool = True) -> int:
    """All nodes in this process on one executor; on one CPU unless ``pin`` is off (``pin_to_one_cpu``).

    Nothing of ROS is torn down (bench_node.spin_in_process): the nodes' DDS participant lives until the process
    ends with bench_engine.process.exit_now, as every command's does; the caller must end it so. The domain's
    ``reservation`` is held as long (process.keep_until_exit), so no later run on this host meets the participant."""
    from bench_engine.bench_node import spin_in_process  # rclpy: planning runs (sweeps, Monte Carlo) loads no ROS

    keep_until_exit(reservation)
    phases.mark("spawned", "launcher", plan.out)
    if pin:
        pin_to_one_cpu(reservation.domain)
    os.environ.update(local_dds_env(reservation.domain))

    def make_nodes() -> list:
        phases.mark("rclpy_init", "launcher", plan.out)
        nodes = [
            node_class(spec.node)(spec.name, plan.run, parameters=_file_parameters(plan, spec.name))
            for spec in plan.graph.start_order()
        ]
        phases.mark("node_created", "launcher", plan.out)
        return nodes

    return spin_in_process(
        reservation.domain, make_nodes, executor, on_exit=lambda: phases.mark("nodes_exited", "launcher", plan.out)
    )
