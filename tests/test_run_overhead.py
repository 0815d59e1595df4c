"""The per-run overhead cuts keep every run the same: nodes forked from the launcher (the default) and Monte
Carlo runs forked from the preloaded fork server record the same messages as fresh processes; the recorder
closes the bag on the source's totals (not after a silence); forked nodes still stop when their launcher is
killed; the phase benchmark (scripts/bench_phases.py) prints every phase. Nothing here asserts a time."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

from graph_helpers import ROOT, SHORT_PASS, digests, read_bag, script

from bench_engine import phases
from bench_engine.batch import run_batch
from bench_engine.launcher import NO_FORK_ENV
from bench_engine.preload import WARM_ENV
from bench_eval.montecarlo import MonteCarlo

PHASE_ROWS = (
    "interpreter + imports",
    "validation",
    "process spawn",
    "node set-up",
    "discovery + readiness",
    "stepping",
    "drain",
    "bag close",
    "shutdown",
    "scoring",
    "exit",
)


def test_forked_and_fresh_node_processes_record_the_same_bag(tmp_path):
    found = {}
    for mode, args, env in (("fresh", ["--fresh-nodes"], {}), ("forked", [], {}), ("single", ["--single-process"], {})):
        out = tmp_path / mode
        res = script(
            "launch.py", "leo_radar", "--seed", "5", *SHORT_PASS, "--out", str(out), "--no-score", *args, extra_env=env
        )
        assert res.returncode == 0, res.stderr[-2000:]
        found[mode] = digests(out / "bag")
        if mode != "single":  # one log per node process, the recorder closed on the source's totals
            assert sorted(p.name for p in (out / "logs").iterdir()) == [
                "ekf.log",
                "radar.log",
                "recorder.log",
                "truth.log",
                "ukf.log",
            ]
            recorder = (out / "logs" / "recorder.log").read_text()
            assert "every message of the run is in" in recorder and "without messages" not in recorder
    assert found["fresh"] == found["forked"] == found["single"]
    assert found["fresh"]["/truth/state"][1] == 201 and found["fresh"]["/clock"][1] == 201


def test_monte_carlo_runs_forked_or_fresh_record_the_same_bags(tmp_path, monkeypatch):
    """A Monte Carlo run (bench_engine.batch, as montecarlo.py makes it; its scoring is other tests') forked from
    the preloaded fork server records what a fresh interpreter records."""
    bags = {}
    for mode in ("fresh", "forked"):
        if mode == "fresh":
            monkeypatch.setenv(NO_FORK_ENV, "1")
        else:
            monkeypatch.delenv(NO_FORK_ENV)
        [spec] = MonteCarlo("leo_radar", tmp_path / mode, 1, seed0=11, overrides=SHORT_PASS[1:]).specs()
        [result] = run_batch([spec], jobs=1)
        assert result.ok, spec.log.read_text()[-2000:]
        assert WARM_ENV not in os.environ  # the fork server's warm-up is its own, not its caller's children's
        bags[mode] = digests(spec.bag)
        assert "[launch] leo_radar" in spec.log.read_text()  # the run's own output, in its log
    assert bags["fresh"] == bags["forked"] and bags["fresh"]["/truth/state"][1] == 201


FORKING_SCRIPT = """
import os
import sys

with open(os.environ["IMPORTS_LOG"], "a") as f:
    f.write(__name__ + "\\n")

from bench_engine.batch_run import fork_context


def child():
    main = sys.modules["__main__"]
    assert main.__file__ == os.environ["SCRIPT"] and main.child is child, (main, child)


if __name__ == "__main__":
    context = fork_context()
    for _ in range(3):
        process = context.Process(target=child)
        process.start()
        process.join()
        assert process.exitcode == 0
"""


def test_the_fork_server_imports_the_command_script_once_for_every_forked_run(tmp_path):
    """A run forked from the fork server finds the command's script as its __main__ (preload.MAIN_ENV) instead of
    importing it again, with all it imports (multiprocessing runs it in each child otherwise)."""
    script_path, log = tmp_path / "forking.py", tmp_path / "imports.log"
    script_path.write_text(FORKING_SCRIPT)
    env = dict(os.environ, IMPORTS_LOG=str(log), SCRIPT=str(script_path))
    env.pop(NO_FORK_ENV, None)
    res = subprocess.run([sys.executable, str(script_path)], env=env, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]
    assert log.read_text().split() == ["__main__", "__mp_main__"]  # the command, then the fork server only


WARMING_SCRIPT = """
from bench_engine.batch_run import fork_context


def child():
    from star_tracker.star_camera import _pair_table

    assert _pair_table.cache_info().currsize == 1, _pair_table.cache_info()


if __name__ == "__main__":
    run = ["star_tracker", "--seed", "3", "--variant", "rotation,sigma_rotation_lo", "--out", "never_written"]
    process = fork_context(warm=run).Process(target=child)
    process.start()
    process.join()
    assert process.exitcode == 0
"""


def test_the_fork_server_builds_the_first_run_once_for_the_runs_forked_from_it(tmp_path):
    """preload.RUN_ENV: a run forked from the server inherits what the first run's validation cached (here a star
    camera's k-vector, shared by every sigma_px of a sweep); that it records the same bag is the forked-or-fresh
    tests' concern."""
    script_path = tmp_path / "warming.py"
    script_path.write_text(WARMING_SCRIPT)
    env = dict(os.environ)
    env.pop(NO_FORK_ENV, None)
    res = subprocess.run(
        [sys.executable, str(script_path)], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120
    )
    assert res.returncode == 0, res.stderr[-2000:]
    assert not (tmp_path / "never_written").exists()


def test_forked_nodes_stop_and_close_the_bag_when_the_launcher_is_killed(tmp_path):
    out, log = tmp_path / "orphan", tmp_path / "phases.jsonl"
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", **{phases.ENV: str(log)})
    proc = subprocess.Popen(
        [
            sys.executable,
            str(ROOT / "scripts" / "launch.py"),
            "leo_radar",
            "--out",
            str(out),
            "--no-score",
            "--set",
            "time.pacing_window=0",
        ],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not (log.exists() and "stepping_start" in log.read_text()):
        assert proc.poll() is None, "the launcher ended before the run started stepping"
        time.sleep(0.1)
    time.sleep(1.0)  # some seconds of sim time into the bag
    nodes = {r["who"]: r["pid"] for r in phases.read(log) if r["event"] == "node_created"}
    assert sorted(nodes) == ["ekf", "radar", "recorder", "truth", "ukf"] and proc.pid not in nodes.values()
    proc.kill()
    proc.wait()

    def alive(pid: int) -> bool:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        return state != "Z"  # a zombie has exited (its parent, the launcher, is gone)

    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and any(alive(p) for p in nodes.values()):
        time.sleep(0.2)
    assert not [n for n, p in nodes.items() if alive(p)], "forked nodes kept running after their launcher died"
    steps = [m.step for _, m in read_bag(out / "bag")["/truth/state"]]
    assert steps and steps == list(range(len(steps)))


def test_phase_benchmark_prints_every_phase_and_the_ratios(tmp_path):
    res = script(
        "bench_phases.py",
        "--modes",
        "single-process,montecarlo",
        "--runs",
        "1",
        "--jobs",
        "1",
        *SHORT_PASS,
        timeout=300,
    )
    assert res.returncode == 0, res.stderr[-2000:]
    lines = res.stdout.splitlines()
    for row in PHASE_ROWS:
        assert any(line.startswith(row) for line in lines), row
    ratio = next(line for line in lines if line.startswith("wall / stepping"))
    assert float(ratio.split()[-1]) > 1.0  # the wall time holds the stepping and more
    mc = next(line for line in lines if "Monte Carlo wall / (stepping / jobs)" in line)
    assert float(mc.split("=")[-1].split(";")[0]) > 1.0
    assert "usage" in script("bench_phases.py", "--help").stdout
