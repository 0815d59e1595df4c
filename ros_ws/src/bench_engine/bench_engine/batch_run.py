"""One run of a Monte Carlo batch (bench_engine.batch): its spec, its process and its result, shared by the
local executor (batch.run_batch) and the Dask one (bench_engine.executors).

Each run is one launcher process (``python -m bench_engine.run``: the graph in one process, real DDS) on a
ROS domain of its own (a free one reserved by bench_engine.domains, or ``domains`` given by the caller), so
parallel runs never hear each other. Locally it is forked from a fork server that has imported everything a
run needs once (bench_engine.preload; multiprocessing's forkserver), so a run does not pay the interpreter
start and the imports again: the same code runs in a fresh process, and the bag is the same as that of a run
made alone (TRACKING_BENCH_NO_FORK=1 starts fresh interpreters instead). A run whose bag holds another number
of truth messages than its steps received messages from a foreign graph on its domain (a process that is not
a bench run): it is set aside (``RUN.crosstalkK``) and run again. A run one of whose nodes was killed by a
signal (the launcher names it), or whose own process was, met an outside event (the OOM killer, an operator, a
chaos test; not SIGINT, SIGTERM or SIGHUP, which stop a run on purpose): it is set aside (``RUN.killedK``, its
log ``RUN.killedK.log``, its partial bag ``RUN.killedK/bag.partial``) and run again, up to NODE_RETRIES times;
with the same seed it records the bag it would have recorded (tests/test_chaos.py).
"""

from __future__ import annotations

import json
import multiprocessing
import os
import re
import signal
import subprocess
import sys
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from multiprocessing import forkserver, spawn
from pathlib import Path

from bench_engine import phases, yamlio
from bench_engine.graph import TRUTH_TOPIC
from bench_engine.launcher import NO_FORK_ENV
from bench_engine.preload import MAIN_ENV, RUN_ENV, WARM_ENV
from bench_engine.process import exit_now
from bench_engine.timegrid import build_time
from bench_engine.views import SWITCH as VIEWS_SWITCH

CROSSTALK_RETRIES = 2
CROSSTALK_EXIT = 3
NODE_RETRIES = 2
"""Attempts more for a run killed from outside: one of its nodes (or its own process) died of a signal other
than STOP_SIGNALS. A node that fails on its own (an exception, exit code 1) is not retried: with the same seed
it would fail again."""
STOP_SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP")
"""Signals that stop a run on purpose (Ctrl-C, an operator, a closing terminal): never retried."""
_KILLED_NODE = re.compile(r"\[launcher\] node '([^']+)' died first \(killed by (SIG\w+|signal \d+)\)")
"""The launcher's line naming a node that died of a signal (bench_engine.launcher._supervise)."""


@dataclass
class RunSpec:
    """One run: scenario (name or YAML path), output directory (the bag is OUT/bag), seed and settings."""

    scenario: str
    out: Path
    seed: int
    estimators: str | None = None
    variant: str | None = None
    overrides: list[str] = field(default_factory=list)
    multiprocess: bool = False
    standard_views: bool = False
    """Publish the standard views (bench_engine.views)? Off in batches unless ``overrides`` set the switch: they
    double the messages of a step (bench_engine.views.SWITCH) and the scorer does not read them."""

    def command(self, domain: int | None) -> list[str]:
        cmd = [
            sys.executable,
            "-m",
            "bench_engine.run",
            self.scenario,
            "--seed",
            str(self.seed),
            "--out",
            str(self.out),
        ]
        if domain is not None:
            cmd += ["--domain-id", str(domain)]
        if self.estimators:
            cmd += ["--estimators", self.estimators]
        if self.variant:
            cmd += ["--variant", self.variant]
        if not self.multiprocess:
            cmd.append("--single-process")
        if not self.standard_views and not any(o.split("=", 1)[0].strip() == VIEWS_SWITCH for o in self.overrides):
            cmd += ["--set", f"{VIEWS_SWITCH}=false"]
        for o in self.overrides:
            cmd += ["--set", o]
        return cmd

    @property
    def bag(self) -> Path:
        return self.out / "bag"

    @property
    def log(self) -> Path:
        return self.out.with_name(self.out.name + ".log")


@dataclass
class RunResult:
    spec: RunSpec
    code: int
    reruns: list[str] = field(default_factory=list)
    killed: list[str] = field(default_factory=list)
    """What was killed in each attempt set aside and run again (e.g. "node 'ukf' (killed by SIGKILL)")."""
    error: str = ""
    """Why the run could not be made at all (the Dask executor: its task failed on every attempt)."""

    @property
    def ok(self) -> bool:
        return self.code == 0 and (self.spec.bag / "metadata.yaml").is_file()


def crosstalk(bag: Path, steps: int) -> bool:
    """True when the bag holds another number of truth messages than the run has steps: another graph on the
    same ROS domain published into this run's topics."""
    info = yamlio.load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    counts = {t["topic_metadata"]["name"]: t["message_count"] for t in info["topics_with_message_count"]}
    return counts.get(TRUTH_TOPIC) != steps


def recorded_steps(bag: Path) -> int:
    """The number of steps of the run a bag recorded (from its run config)."""
    return build_time(yamlio.load((bag / "run_config.yaml").read_text())["scenario"]).steps


PRELOAD = "bench_engine.preload"
EXIT_LINE = "[batch] exit code "
"""The last line a forked run writes to its log: its exit code, should the fork server lose it (multiprocessing
then reports 255, as when the fork server itself is gone)."""
_fork_lock = threading.Lock()
_fork_context = None


def _forked_run(argv: list[str], log: str) -> None:
    """A run in a process forked from the fork server: ``python -m bench_engine.run ARGV > LOG 2>&1``."""
    fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    os.close(fd)
    from bench_engine.run import main  # sets a node's environment when imported: only in the forked run

    code = main(argv)
    print(f"{EXIT_LINE}{code}", file=sys.stderr, flush=True)
    exit_now(code)  # as bench_engine.run's own end: the run's ROS objects are left to it (launcher.run_single_process)


def fork_context(warm: list[str] | None = None):
    """The forkserver context whose server has imported PRELOAD and the command's script (preload.MAIN_ENV), or
    None where runs cannot be forked. ``warm``: the arguments of a run (bench_engine.run's) whose objects the
    server builds once as it starts (preload.RUN_ENV), for every run forked from it to inherit what they cache."""
    global _fork_context
    if os.environ.get(NO_FORK_ENV) == "1" or sys.platform != "linux":
        return None
    with _fork_lock:
        if _fork_context is None:
            os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
            os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
            os.environ[WARM_ENV] = "1"  # the fork server (started with this environment) imports everything
            main = spawn.get_preparation_data("fork server").get("init_main_from_path")
            if main:
                os.environ[MAIN_ENV] = main  # ... and the command's script (preload.MAIN_ENV)
            if warm:
                os.environ[RUN_ENV] = json.dumps(warm)  # ... and builds a run's objects (preload.RUN_ENV)
            try:
                context = multiprocessing.get_context("forkserver")
                context.set_forkserver_preload([PRELOAD])
                forkserver.ensure_running()  # now, while WARM_ENV is set ...
            finally:
                del os.environ[WARM_ENV]  # ... and only for it: this process's other children import as usual
                os.environ.pop(MAIN_ENV, None)
                os.environ.pop(RUN_ENV, None)
            _fork_context = context
    return _fork_context


def launch_run(cmd: list[str], log: Path, **popen) -> int:
    """Run ``python -m bench_engine.run ...`` (``cmd``, as RunSpec.command gives it) with its output to
    ``log``; forked from the fork server unless ``popen`` asks for a subprocess's own settings (the Dask
    executor) or runs cannot be forked. Returns the exit code (-N: killed by signal N)."""
    context = None if popen else fork_context(warm=cmd[3:])
    if context is None:
        with open(log, "w") as f:
            return subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT, **popen).returncode
    process = context.Process(target=_forked_run, args=(cmd[3:], str(log)), name=f"run {log.stem}")
    process.start()
    process.join()
    if process.exitcode == 255:  # the status never came back: the run's own last word, if it got that far
        lines = log.read_text(errors="replace").splitlines() if log.exists() else []
        if lines and lines[-1].startswith(EXIT_LINE):
            return int(lines[-1][len(EXIT_LINE) :])
    return process.exitcode


def killed_from_outside(code: int, log: Path) -> str | None:
    """What killed a failed run from outside, from its exit code and its log (the launcher names a node that
    died of a signal): "node 'ukf' (killed by SIGKILL)", "its own process (killed by SIGKILL)", or None for a
    run that completed, failed on its own, or was stopped on purpose (STOP_SIGNALS)."""
    if code < 0:
        try:
            killers = [("its own process", signal.Signals(-code).name)]
        except ValueError:
            killers = [("its own process", f"signal {-code}")]
    elif code == 1 and log.is_file():
        killers = [(f"node '{name}'", how) for name, how in _KILLED_NODE.findall(log.read_text(errors="replace"))]
    else:
        return None
    if not killers or any(how in STOP_SIGNALS for _, how in killers):
        return None
    return ", ".join(f"{who} (killed by {how})" for who, how in killers)


def _set_aside(spec: RunSpec, tag: str, with_log: bool = False) -> str:
    """Rename OUT to the first free OUT.TAGk (and OUT.log to OUT.TAGk.log with ``with_log``, the partial bag to
    OUT.TAGk/bag.partial, so that ``OUT/run_*/bag`` never matches it); returns the new name."""
    k = 0
    while (aside := spec.out.with_name(f"{spec.out.name}.{tag}{k}")).exists() or aside.with_name(
        aside.name + ".log"
    ).exists():
        k += 1
    if spec.out.exists():
        spec.out.rename(aside)
    if with_log:
        if (aside / "bag").exists():
            (aside / "bag").rename(aside / "bag.partial")
        if spec.log.exists():
            spec.log.rename(aside.with_name(aside.name + ".log"))
    return aside.name


def run_one(spec: RunSpec, domain: int | None, report: Callable[[str], None] | None = None, **popen) -> RunResult:
    """Run ``spec``, again after cross-talk (up to CROSSTALK_RETRIES times) or after a node was killed (up to
    NODE_RETRIES times; ``report`` is called with a line naming the run and what died, as each retry starts);
    its log is OUT.log. ``popen``: extra subprocess arguments (the Dask executor's environment)."""
    spec.out.parent.mkdir(parents=True, exist_ok=True)
    result = RunResult(spec, CROSSTALK_EXIT)
    attempts = crosstalks = 0
    while True:
        attempts += 1
        phases.mark("run_spawn", "batch", spec.out.resolve())
        code = launch_run(spec.command(domain), spec.log, **popen)
        phases.mark("run_exited", "batch", spec.out.resolve())
        if code == 0 and (spec.bag / "metadata.yaml").is_file() and crosstalk(spec.bag, recorded_steps(spec.bag)):
            aside = _set_aside(spec, "crosstalk")
            result.reruns.append(f"{spec.out}: foreign messages on its ROS domain, set aside as {aside}")
            crosstalks += 1
            if crosstalks > CROSSTALK_RETRIES:
                result.code = CROSSTALK_EXIT
                return result
            continue
        what = killed_from_outside(code, spec.log)
        if what is None or len(result.killed) >= NODE_RETRIES:
            result.code = code
            if what is not None:
                result.error = f"{what}, again after {NODE_RETRIES} retries"
            return result
        aside = _set_aside(spec, "killed", with_log=True)
        result.killed.append(what)
        note = (
            f"{spec.out}: {what} in attempt {attempts}; set aside as {aside}, running it again "
            f"(retry {len(result.killed)} of {NODE_RETRIES})"
        )
        result.reruns.append(note)
        if report is not None:
            report(note)


def complete(out: Path) -> bool:
    """Whether run directory ``out`` holds a complete bag (closed: metadata.yaml, with its run config)."""
    return (out / "bag" / "metadata.yaml").is_file() and (out / "bag" / "run_config.yaml").is_file()
