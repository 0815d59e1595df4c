"""The launcher's promises: bad input stops it before anything starts; signals and dead nodes leave a
complete bag (a killed recorder's is recovered); normal runs leave no shared-memory files behind."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterable
from pathlib import Path

import pytest
from graph_helpers import ROOT, SHORT_PASS, launch_in_background, node_pid, read_bag, script, wait_for_stepping

from bench_engine import launcher
from bench_engine.domains import reserve


@pytest.mark.parametrize(
    "args, message",
    [
        (["--estimators", "ekf,kalman9000"], "'filters.kalman9000.type' must be one of"),
        (["--set", "sensors.radar.sigma_rnge=3"], "unknown key(s) 'sensors.radar.sigma_rnge'"),
        (["--set", "sensors.radar.sigma_range=-1"], "'sensors.radar.sigma_range' must be > 0, got -1.0"),
        (["--set", "sensors.radar.p_detect=1.5"], "'sensors.radar.p_detect' must be in [0, 1], got 1.5"),
        (["--set", "colour=blue"], "unknown key(s) 'colour' in the scenario's top level"),
        (["--set", "filters.ukf.params.alpha=-1"], "alpha"),
        (["--variant", "nope"], "unknown variant 'nope'; allowed: iss, table3_angles"),
        (["--set", "filters.ukf.params.alpha=abc"], "'filters.ukf.params.alpha' must be a number, got 'abc'"),
        (["--set", "time.duration=1e12"], "gives 10000000000001 steps; a run may have at most 10000000"),
    ],
)
def test_bad_input_stops_before_anything_starts(tmp_path: Path, args: list[str], message: str) -> None:
    out = tmp_path / "bad"
    res = script("launch.py", "leo_radar", "--out", str(out), *args, timeout=60)
    assert res.returncode == 2
    assert message in res.stderr
    assert not (out / "bag").exists()


def test_unknown_scenario_lists_the_available_ones(tmp_path: Path) -> None:
    res = script("launch.py", "leo_radr", "--out", str(tmp_path / "x"), timeout=60)
    assert res.returncode == 2 and "unknown scenario 'leo_radr'; available: " in res.stderr
    assert "leo_radar" in res.stderr


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_leaves_a_complete_readable_bag(tmp_path: Path, sig: int) -> None:
    out = tmp_path / "sig"
    proc = launch_in_background(out)
    wait_for_stepping(out, proc)
    proc.send_signal(sig)
    proc.wait(timeout=60)
    assert proc.returncode == 128 + sig
    bag = read_bag(out / "bag")
    steps = [m.step for _, m in bag["/truth/state"]]
    assert len(steps) > 10 and steps == list(range(len(steps)))  # nothing lost before the interruption
    assert "/ukf/estimate" in bag


def test_dead_node_is_named_and_bag_closed(tmp_path: Path) -> None:
    out = tmp_path / "dead"
    proc = launch_in_background(out)
    wait_for_stepping(out, proc)
    os.kill(node_pid(out, "ekf"), signal.SIGKILL)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 1
    assert "node 'ekf' died first (killed by SIGKILL)" in err
    assert read_bag(out / "bag")["/truth/state"]


def test_a_killed_recorder_is_named_and_its_bag_recovered(tmp_path: Path) -> None:
    """SIGKILL leaves the recorder no chance to close the bag; the launcher names it and rebuilds the bag from
    the chunks it flushed (every second of sim time), which the independent reader then opens."""
    out = tmp_path / "killed"
    proc = launch_in_background(out)
    wait_for_stepping(out, proc)
    os.kill(node_pid(out, "recorder"), signal.SIGKILL)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 1
    assert "node 'recorder' died first (killed by SIGKILL)" in err
    assert "recovered" in err and (out / "bag" / "metadata.yaml").is_file()
    assert list((out / "bag").glob("*.mcap.truncated"))
    bag = read_bag(out / "bag")
    steps = sorted(m.step for _, m in bag["/truth/state"])
    assert len(steps) >= 10 and steps == list(range(len(steps)))  # whole seconds of sim time, nothing skipped
    assert {"/radar/measurement", "/ekf/estimate", "/ukf/estimate"} <= set(bag)


SHM = Path("/dev/shm")


def _shm_files_of(pids: Iterable[str]) -> set[str]:
    """The Fast DDS files in /dev/shm that processes ``pids`` map (segments, port queues) or hold open (their
    ``_el`` lock files)."""
    found = set()
    for pid in pids:
        try:
            found.update(re.findall(r"/dev/shm/(fastrtps_\S+)", Path(f"/proc/{pid}/maps").read_text()))
            for fd in Path(f"/proc/{pid}/fd").iterdir():
                target = os.readlink(fd)
                if target.startswith("/dev/shm/fastrtps_"):
                    found.add(target[len("/dev/shm/") :])
        except OSError:  # the process ended meanwhile, or is not ours to read
            continue
    return found


def _pids(*, command_with: str = "", also: int | None = None) -> list[str]:
    """Every process (``command_with``: only those whose command line contains it, and ``also``)."""
    pids = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            if command_with in (entry / "cmdline").read_bytes().decode(errors="replace") or entry.name == str(also):
                pids.append(entry.name)
        except OSError:
            continue
    return pids


@pytest.mark.skipif(not SHM.is_dir() or not Path("/proc/self/maps").is_file(), reason="needs /dev/shm and /proc")
def test_normal_runs_leave_no_shared_memory_behind(tmp_path: Path) -> None:
    """Only this run's Fast DDS files count (other test sessions and runs share /dev/shm): those its own
    processes (the launcher and every node, found by the run's output path) map or hold while it runs and that
    were not there before it started. None of them may be left once it has ended, unless another live process
    uses it now. (Files the run used but found there, e.g. a port queue another run left, are not its own.)"""
    out = tmp_path / "shm"
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    before = {p.name for p in SHM.glob("fastrtps_*")}
    log = tmp_path / "launch.log"
    with open(log, "w") as f:
        proc = subprocess.Popen(
            [
                sys.executable,
                str(ROOT / "scripts" / "launch.py"),
                "leo_radar",
                "--out",
                str(out),
                "--no-score",
                "--set",
                "time.duration=5",
            ],
            env=env,
            stdout=f,
            stderr=f,
        )
    ours: set[str] = set()
    while proc.poll() is None:
        ours |= _shm_files_of(_pids(command_with=str(out), also=proc.pid))
        time.sleep(0.02)
    assert proc.returncode == 0, log.read_text()[-2000:]
    assert ours, "the run's processes were never seen using Fast DDS shared memory"
    left = {name for name in ours - before if (SHM / name).exists()}
    assert left - _shm_files_of(_pids()) == set()


def test_montecarlo_runs_in_parallel_domains_and_aggregates(tmp_path: Path) -> None:
    out = tmp_path / "mc"
    res = script(
        "montecarlo.py",
        "leo_radar",
        "--runs",
        "2",
        "--jobs",
        "2",
        "--out",
        str(out),
        "--json",
        *SHORT_PASS,
        timeout=600,
    )
    assert res.returncode == 0, res.stderr[-3000:]
    scored = json.loads(res.stdout)
    assert scored["runs"] == 2 and set(scored["estimators"]) == {"ekf", "ukf"}
    assert all((out / f"run_{i:03d}" / "bag" / "metadata.yaml").is_file() for i in range(2))
    assert (out / "report" / "report.md").is_file()
    # seeds differ between runs: the measurement noise differs
    r0 = [m.range for _, m in read_bag(out / "run_000" / "bag")["/radar/measurement"]][:5]
    r1 = [m.range for _, m in read_bag(out / "run_001" / "bag")["/radar/measurement"]][:5]
    assert r0 != r1


def test_a_domain_held_by_another_run_is_refused(tmp_path: Path) -> None:
    held = reserve(None)  # a free one: another test session may hold any fixed id
    try:
        res = script(
            "launch.py", "leo_radar", "--out", str(tmp_path / "busy"), "--domain-id", str(held.domain), timeout=60
        )
    finally:
        held.release()
    assert res.returncode == 2
    assert f"ROS_DOMAIN_ID {held.domain} is in use by another bench run" in res.stderr


def test_nodes_stop_and_close_the_bag_when_the_launcher_is_killed(tmp_path: Path) -> None:
    out = tmp_path / "orphan"
    proc = launch_in_background(out)
    wait_for_stepping(out, proc)
    proc.kill()
    proc.wait()
    pattern = f"--config {out.resolve()}/run_config.yaml"
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        alive = subprocess.run(["pgrep", "-f", "--", pattern], capture_output=True, text=True).stdout.split()
        if not alive:
            break
        time.sleep(0.5)
    assert not alive, "nodes kept running after their launcher died"
    steps = [m.step for _, m in read_bag(out / "bag")["/truth/state"]]
    assert steps == list(range(len(steps))) and steps


def test_a_run_with_nothing_to_score_ends_with_one_line(tmp_path: Path) -> None:
    """A radar that never detects: the filters publish nothing; the launcher says so in one line, exit 1."""
    res = script(
        "launch.py",
        "leo_radar",
        "--out",
        str(tmp_path / "none"),
        "--set",
        "time.duration=5",
        "--set",
        "sensors.radar.p_detect=0.0",
        timeout=120,
    )
    assert res.returncode == 1 and "Traceback" not in res.stderr
    assert "error: no estimates in" in res.stderr and (tmp_path / "none" / "bag" / "metadata.yaml").is_file()


def test_a_node_lingering_after_a_complete_run_is_stopped_and_named(tmp_path: Path, monkeypatch, capsys) -> None:
    """The run is complete once its source (and recorder) exited cleanly; a node still up LINGER_S later is
    stopped with a warning and the run still succeeds. Real processes stand in for the nodes: the supervisor
    only sees processes."""
    plan = launcher.prepare_run("leo_radar", tmp_path / "linger", record=False, overrides=list(SHORT_PASS[1::2]))
    plan.logs.mkdir(exist_ok=True)
    monkeypatch.setattr(launcher, "LINGER_S", 1.0)

    def default_sigint() -> None:  # as a node has, even where the test runs with SIGINT ignored (a background job)
        signal.signal(signal.SIGINT, signal.SIG_DFL)

    procs = {
        spec.name: subprocess.Popen(["sleep", "60"] if spec.name == "ekf" else ["true"], preexec_fn=default_sigint)
        for spec in plan.graph.nodes
    }
    assert launcher._supervise(plan, procs, [], timeout_s=60, quiet=True) == 0
    assert "node 'ekf' had not exited 1 s after the run completed" in capsys.readouterr().err
    assert procs["ekf"].returncode == -signal.SIGINT


def test_a_recorder_hanging_after_closing_its_bag_is_stopped_and_the_run_succeeds(
    tmp_path: Path, monkeypatch, capsys
) -> None:
    """Once the bag is closed (its metadata.yaml written) the run is complete even if the recorder never exits
    (seen under load: the recorder spinning in Fast DDS's destroy_participant after closing its bag, and the Monte
    Carlo waiting for it for good). Here the recorder and the source hang with SIGINT ignored: both are stopped,
    SIGKILL after the grace, and the run succeeds."""
    plan = launcher.prepare_run("leo_radar", tmp_path / "hang", overrides=list(SHORT_PASS[1::2]))
    plan.logs.mkdir(exist_ok=True)
    plan.bag_dir.mkdir(parents=True, exist_ok=True)
    monkeypatch.setattr(launcher, "LINGER_S", 1.0)
    monkeypatch.setattr(launcher, "_recover_bag", lambda plan: None)  # the stand-in bag has no data to check
    hanging = {"recorder", "truth"}
    procs = {
        spec.name: subprocess.Popen(["sh", "-c", "trap '' INT; exec sleep 60"] if spec.name in hanging else ["true"])
        for spec in plan.graph.nodes
    }
    (plan.bag_dir / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    assert launcher._supervise(plan, procs, [], timeout_s=60, quiet=True) == 0
    err = capsys.readouterr().err
    assert all(f"node '{name}' had not exited 1 s after the run completed" in err for name in hanging)
    assert all(procs[name].returncode == -signal.SIGKILL for name in hanging)


HANGING_TEARDOWN = """
import time, rclpy
from rclpy.node import Node
from bench_engine import bench_node

class Finished(Node):
    finished, failed = True, None

    def destroy_node(self):
        print("destroying", flush=True)
        time.sleep(3600)

bench_node.TEARDOWN_S = 1.0
rclpy.init()
print("spin_nodes returned", bench_node.spin_nodes([Finished("finished")]), flush=True)
"""


def test_a_process_whose_ros_teardown_hangs_ends_after_the_teardown_deadline(tmp_path: Path) -> None:
    """A node closed, then stuck in rclpy's teardown (as Fast DDS's destroy_participant once spun for good): where
    nodes are torn down (a node process, a standalone node) the process ends after TEARDOWN_S with the stuck
    thread's traceback and exit code 1, instead of hanging. (A single-process run tears nothing down: below.)"""
    domain = reserve(None)
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(domain.domain))
    res = subprocess.run([sys.executable, "-c", HANGING_TEARDOWN], env=env, capture_output=True, text=True, timeout=60)
    domain.release()
    assert res.returncode == 1 and "destroying" in res.stdout and "spin_nodes returned" not in res.stdout
    assert "Timeout (0:00:01)!" in res.stderr and "destroy_node" in res.stderr


SPINNING_TEARDOWN = """
import sys, time
import rclpy, rclpy.context, rclpy.executors, rclpy.node
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

def spin_for_good(*args, **kwargs):  # as Fast DDS's destroy_participant once did, under load
    print("teardown entered", flush=True)
    while True:
        time.sleep(1)

for owner, names in [(rclpy.node.Node, ["destroy_node"]), (rclpy.executors.Executor, ["remove_node", "shutdown"]),
                     (_rclpy.EventsExecutor, ["remove_node", "shutdown"]), (rclpy, ["shutdown", "try_shutdown"]),
                     (rclpy.context.Context, ["shutdown", "try_shutdown"])]:
    for name in names:
        setattr(owner, name, spin_for_good)
from bench_eval.cli.launch import command
sys.argv = ["launch.py", *sys.argv[1:]]
command()
"""


def test_a_single_process_run_ends_with_its_results_whatever_rclpy_teardown_would_do(tmp_path: Path) -> None:
    """Every way rclpy tears down nodes, executors and the context spins for good here, as Fast DDS's
    destroy_participant once did: a single-process run still records its complete bag, scores it, leaves no
    shared-memory file of its own and exits 0, since nothing after the run's end waits on the teardown
    (bench_engine.bench_node.spin_in_process). Before, the run hung in destroy_node until TEARDOWN_S ended it
    with exit code 1; without any deadline it would hang for good (the subprocess's timeout here)."""
    out = tmp_path / "spin"
    before = {p.name for p in SHM.glob("fastrtps_*")} if SHM.is_dir() else set()
    with open(tmp_path / "out.txt", "w+") as stdout, open(tmp_path / "err.txt", "w+") as stderr:
        proc = subprocess.Popen(
            [
                sys.executable,
                "-c",
                SPINNING_TEARDOWN,
                "leo_radar",
                "--single-process",
                "--out",
                str(out),
                "--set",
                "time.duration=5",
                "--json",
            ],
            env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"),
            stdout=stdout,
            stderr=stderr,
            text=True,
        )
        ours: set[str] = set()
        hung = time.monotonic() + 240.0  # a hang's limit, not a speed: the run takes a few seconds
        try:
            while proc.poll() is None:  # the files its participant maps or holds
                if time.monotonic() > hung:
                    raise subprocess.TimeoutExpired(proc.args, 240.0)
                ours |= _shm_files_of([str(proc.pid)])
                time.sleep(0.02)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        stdout.seek(0), stderr.seek(0)
        out_text, err_text = stdout.read(), stderr.read()
    assert proc.returncode == 0 and "teardown entered" not in out_text, err_text[-3000:]
    assert json.loads(out_text)["runs"] == 1 and (out / "score.json").is_file()
    steps = [m.step for _, m in read_bag(out / "bag")["/truth/state"]]
    assert steps == list(range(51))
    if SHM.is_dir():  # its participant was never destroyed; its files went with the run all the same
        assert ours and {name for name in ours - before if (SHM / name).exists()} - _shm_files_of(_pids()) == set()
