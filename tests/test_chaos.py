"""Chaos: a Monte Carlo batch survives node processes killed in the middle of its runs (issue 18, item 3).

Design. A fault-free batch (montecarlo.py, the local executor) and, for each executor (local, and Dask on a
LocalCluster: ``--scheduler local``), the same batch while a killer thread in this process SIGKILLs one node
process of some runs. Every batch has the same seeds and settings: leo_radar, one process per node
(``--multiprocess``: a node can be killed without its run), 30 s of sim time, strict lock-step
(``time.pacing_window=0``: about a second of stepping, a window the killer cannot miss). The killer's plan is
seeded: which runs, which node of each (the kinds in turn: a filter, the recorder, the sensor; which filter is
drawn) and how long after the run starts stepping (0-0.3 s). It watches each chosen run's truth log, waits for
"stepping", waits its delay, finds the node by its command line (``--name NODE --config RUN/run_config.yaml``) and
kills it, once: the retry of that run is left alone. The launcher names the node, the batch sets the attempt aside
(RUN.killed0) and runs it again (bench_engine.batch_run.run_one), and the batch's score.json equals the
fault-free one value for value, except ``runs_per_minute`` (wall time: a batch with retries is slower); each
run's bag holds the same messages as the fault-free run's (per-topic digests).

Budget: 3 runs on 2 jobs, 2 of them disturbed (a filter and the recorder), per executor: about a minute in
all on 2 busy cores (the Dask batch is the slower: its runs are fresh interpreters, not forked).
A larger campaign: BENCH_CHAOS_RUNS=N (runs per batch), BENCH_CHAOS_KILLS=K (disturbed runs, <= N; the
kinds cycle filter, recorder, sensor), BENCH_CHAOS_SEED=S (the killer's plan), e.g.
``BENCH_CHAOS_RUNS=12 BENCH_CHAOS_KILLS=9 .venv/bin/python -m pytest tests/test_chaos.py``.
"""

from __future__ import annotations

import itertools
import json
import os
import random
import signal
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import pytest
from graph_helpers import digests, script

import bench_engine.batch_run as batch_run
from bench_engine.batch_run import NODE_RETRIES, RunSpec, killed_from_outside, run_one

RUNS = int(os.environ.get("BENCH_CHAOS_RUNS", "3"))
KILLS = int(os.environ.get("BENCH_CHAOS_KILLS", "2"))
SEED = int(os.environ.get("BENCH_CHAOS_SEED", "18"))
ARGS = [
    "leo_radar",
    "--runs",
    str(RUNS),
    "--jobs",
    "2",
    "--multiprocess",
    "--set",
    "time.duration=30",
    "--set",
    "time.pacing_window=0",
    "--json",
]
NODES = {"filter": ("ekf", "ukf"), "recorder": ("recorder",), "sensor": ("radar",)}
"""leo_radar's node processes by kind (its truth source is not a target: the brief is sensors, filters and the
recorder)."""
WALL_CLOCK_KEYS = {"runs_per_minute"}
"""score.json keys that measure the batch's wall time, not its runs: a batch with retries takes longer."""
TIMEOUT_S = 240 + 45 * RUNS


@dataclass
class Target:
    run: Path
    node: str
    delay: float
    killed_pid: int | None = None
    note: str = ""


def kill_plan(root: Path, seed: int = SEED, runs: int = RUNS, kills: int = KILLS) -> list[Target]:
    """Which runs of the batch in ``root`` lose which node, how long after they start stepping: seeded."""
    rng = random.Random(seed)
    kinds = itertools.cycle(("filter", "recorder", "sensor"))
    return [
        Target(root / f"run_{i:03d}", rng.choice(NODES[next(kinds)]), rng.uniform(0.0, 0.3))
        for i in sorted(rng.sample(range(runs), kills))
    ]


def node_pids(run: Path, node: str) -> list[int]:
    """Live processes of node ``node`` of run directory ``run`` (forked nodes set their command line to what a
    fresh node process would have; a fresh one has it NUL-separated)."""
    pattern = f"--name {node} --config {run.resolve() / 'run_config.yaml'} "
    found = []
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            cmdline = (proc / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            state = (proc / "stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if pattern in cmdline + " " and state not in ("Z", "X"):
            found.append(int(proc.name))
    return found


class Killer(threading.Thread):
    """Kills each target's node once, ``delay`` after its run's truth says it is stepping."""

    def __init__(self, targets: list[Target]) -> None:
        super().__init__(daemon=True, name="chaos-killer")
        self.targets = targets
        self.stop = threading.Event()

    def run(self) -> None:
        stepping: dict[Path, float] = {}
        pending = list(self.targets)
        while pending and not self.stop.is_set():
            for target in list(pending):
                log = target.run / "logs" / "truth.log"
                if target.run not in stepping:
                    try:
                        if "stepping" in log.read_text(errors="replace"):
                            stepping[target.run] = time.monotonic()
                    except OSError:
                        pass
                    continue
                if time.monotonic() - stepping[target.run] < target.delay:
                    continue
                pending.remove(target)  # one try only: the run's retry must be left to finish
                pids = node_pids(target.run, target.node)
                if len(pids) != 1:
                    target.note = f"found {len(pids)} processes of node '{target.node}'"
                    continue
                try:
                    os.kill(pids[0], signal.SIGKILL)
                    target.killed_pid = pids[0]
                except ProcessLookupError:
                    target.note = f"node '{target.node}' exited before it could be killed"
            time.sleep(0.005)


def scores(out: Path) -> dict:
    found = json.loads((out / "score.json").read_text())
    return {k: v for k, v in found.items() if k not in WALL_CLOCK_KEYS}


@pytest.fixture(scope="module")
def fault_free(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("chaos") / "fault_free"
    res = script("montecarlo.py", *ARGS, "--out", str(out), timeout=TIMEOUT_S)
    assert res.returncode == 0, res.stderr[-3000:]
    assert not list(out.glob("*.killed*")) and "after a killed node" not in res.stderr
    return out


@pytest.mark.parametrize("executor", ["local", "dask"])
def test_a_batch_whose_nodes_are_killed_retries_them_and_scores_as_the_fault_free_batch(
    fault_free: Path, tmp_path: Path, executor: str
) -> None:
    out = tmp_path / "chaos"
    targets = kill_plan(out)
    killer = Killer(targets)
    killer.start()
    started = time.monotonic()
    try:
        res = script(
            "montecarlo.py",
            *ARGS,
            "--out",
            str(out),
            *(["--scheduler", "local"] if executor == "dask" else []),
            timeout=TIMEOUT_S,
        )
    finally:
        killer.stop.set()
        killer.join(timeout=5)
    wall = time.monotonic() - started
    assert res.returncode == 0, res.stderr[-3000:]
    for t in targets:
        assert t.killed_pid is not None, f"{t.run.name}: {t.note or 'never seen stepping'}"
    print(
        f"\n[chaos] {executor}: {RUNS} runs, {len(targets)} disturbed "
        f"({', '.join(f'{t.run.name}: {t.node}' for t in targets)}), {wall:.0f} s"
    )

    disturbed = {t.run.name: t for t in targets}
    for t in targets:
        aside = t.run.with_name(t.run.name + ".killed0")
        # the launcher named the node that was killed, in the set-aside attempt's log
        assert (
            f"[launcher] node '{t.node}' died first (killed by SIGKILL)"
            in aside.with_name(aside.name + ".log").read_text()
        )
        # it was killed mid-run: that attempt's truth started stepping and never finished
        truth = (aside / "logs" / "truth.log").read_text()
        assert "stepping" in truth and " steps in " not in truth, truth
        # one line per retry, naming the run and the node
        line = (
            f"[montecarlo] {t.run}: node '{t.node}' (killed by SIGKILL) in attempt 1; set aside as "
            f"{aside.name}, running it again (retry 1 of {NODE_RETRIES})"
        )
        assert res.stderr.count(line) == 1, res.stderr[-3000:]
        assert not t.run.with_name(t.run.name + ".killed1").exists()  # the retry was left to finish
    assert sorted(p.name for p in out.glob("*.killed*") if p.is_dir()) == sorted(f"{n}.killed0" for n in disturbed)
    assert f"; {len(targets)} run(s) retried after a killed node ({len(targets)} retries)" in res.stderr

    assert scores(out) == scores(fault_free)
    for i in range(RUNS):
        run = f"run_{i:03d}"
        assert digests(out / run / "bag") == digests(fault_free / run / "bag"), run


# --- the retry rule itself, without ROS: which failures are run again, how often, and what is kept


@pytest.mark.parametrize(
    "code, log, expected",
    [
        (1, "[launcher] node 'ukf' died first (killed by SIGKILL); log: x/ukf.log\n", "node 'ukf' (killed by SIGKILL)"),
        (1, "[launcher] node 'radar' died first (killed by SIGSEGV); log: x\n", "node 'radar' (killed by SIGSEGV)"),
        (-9, "", "its own process (killed by SIGKILL)"),
        (1, "[launcher] node 'ekf' died first (exit code 1); log: x\n", None),  # its own failure: it would fail again
        (1, "[launcher] node 'ekf' died first (killed by SIGTERM); log: x\n", None),  # stopped on purpose
        (-2, "", None),
        (130, "[launcher] interrupted; bag closed at x\n", None),
        (0, "[launcher] node 'ukf' died first (killed by SIGKILL)\n", None),
        (2, "error: unknown key(s) 'x'\n", None),
    ],
)
def test_only_runs_killed_from_outside_are_retried(tmp_path: Path, code: int, log: str, expected: str | None) -> None:
    (tmp_path / "run.log").write_text(log)
    assert killed_from_outside(code, tmp_path / "run.log") == expected


def fake_launches(monkeypatch, tmp_path: Path, codes: list[int]) -> list[int]:
    """Replace the run process: each attempt writes OUT/bag and OUT.log and returns the next of ``codes``
    (1: the launcher named a node killed by SIGKILL)."""
    calls = []

    def launch(cmd, log, **_popen):
        out = Path(cmd[cmd.index("--out") + 1])
        (out / "bag").mkdir(parents=True)
        (out / "bag" / "attempt").write_text(str(len(calls)))
        code = codes[len(calls)]
        Path(log).write_text("[launcher] node 'recorder' died first (killed by SIGKILL); log: r\n" if code == 1 else "")
        calls.append(code)
        return code

    monkeypatch.setattr(batch_run, "launch_run", launch)
    return calls


def test_a_killed_run_is_set_aside_and_run_again_a_bounded_number_of_times(monkeypatch, tmp_path: Path) -> None:
    spec = RunSpec("leo_radar", tmp_path / "run_000", 1)
    lines = []
    calls = fake_launches(monkeypatch, tmp_path, [1] * (NODE_RETRIES + 1))
    result = run_one(spec, None, lines.append)
    assert len(calls) == NODE_RETRIES + 1 and result.code == 1 and not result.ok
    assert result.killed == ["node 'recorder' (killed by SIGKILL)"] * NODE_RETRIES and result.reruns == lines
    assert lines[0] == (
        f"{spec.out}: node 'recorder' (killed by SIGKILL) in attempt 1; set aside as "
        f"run_000.killed0, running it again (retry 1 of {NODE_RETRIES})"
    )
    assert result.error == f"node 'recorder' (killed by SIGKILL), again after {NODE_RETRIES} retries"
    for k in range(NODE_RETRIES):  # each set-aside attempt keeps its log; its partial bag is out of run_*/bag
        aside = tmp_path / f"run_000.killed{k}"
        assert (aside / "bag.partial" / "attempt").read_text() == str(k) and not (aside / "bag").exists()
        assert "died first" in (tmp_path / f"run_000.killed{k}.log").read_text()
    assert (spec.bag / "attempt").read_text() == str(NODE_RETRIES)  # the last attempt stays where it was


def test_a_run_that_completes_on_its_retry_is_kept(monkeypatch, tmp_path: Path) -> None:
    spec = RunSpec("leo_radar", tmp_path / "run_003", 4)
    calls = fake_launches(monkeypatch, tmp_path, [1, 0])
    (tmp_path / "run_003.killed0").mkdir()  # left by an earlier batch: the next free name is taken
    result = run_one(spec, None)
    assert calls == [1, 0] and result.code == 0 and result.killed == ["node 'recorder' (killed by SIGKILL)"]
    assert (tmp_path / "run_003.killed1" / "bag.partial").is_dir() and (spec.bag / "attempt").read_text() == "1"
