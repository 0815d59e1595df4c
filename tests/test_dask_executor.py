"""The Dask executor of the one Monte Carlo runner (bench_engine.executors) against the local one, on a
LocalCluster on 127.0.0.1: a sweep made on the cluster is resumed by the local executor, a run whose worker is
killed is run again and records what the local executor records, and --resume keeps the complete runs. That a
Dask batch scores as the local one, value for value and bag for bag, is tests/test_chaos.py's comparison (its
Dask batch, on ``--scheduler local``, against the fault-free local batch). Short leo_radar passes (20 s of sim
time) keep it quick."""

from __future__ import annotations

import json
import os
import shutil
import signal
import sys
import threading
import time
from pathlib import Path

import cloudpickle
import pytest
from dask.distributed import LocalCluster
from graph_helpers import SHORT_PASS, digests, script
from test_sweep import scenario_with

from bench_engine.batch import RunSpec, complete, run_batch
from bench_engine.executors import run_dask, run_task
from bench_eval.montecarlo import MonteCarlo

RUNS = ["--runs", "2", "--jobs", "2", *SHORT_PASS]


@pytest.fixture(scope="module")
def cluster():
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None) as c:
        yield c


@pytest.fixture(scope="module")
def local_mc(tmp_path_factory) -> Path:
    """The runs of ``montecarlo.py leo_radar RUNS`` (its MonteCarlo's specs: seeds 1 and 2), made by the default
    local executor (bench_engine.batch; not scored: montecarlo.py --resume scores them in test_resume_...)."""
    out = tmp_path_factory.mktemp("local") / "mc"
    results = run_batch(MonteCarlo("leo_radar", out, 2, overrides=SHORT_PASS[1:]).specs(), jobs=2)
    assert all(r.ok for r in results), [r.spec.log.read_text()[-2000:] for r in results if not r.ok]
    return out


def test_a_batch_run_records_what_the_same_seed_records_alone(local_mc, tmp_path):
    """Run 1 (seed 2) alone, one process per node, records the same messages as in the batch, and the standard
    views besides (a batch runs without them: bench_engine.batch_run.RunSpec.standard_views). (That a Dask batch
    equals the local one, value for value and bag for bag, is tests/test_chaos.py's fault-free comparison.)"""
    alone = tmp_path / "alone"
    res = script("launch.py", "leo_radar", "--seed", "2", *SHORT_PASS, "--out", str(alone), "--no-score")
    assert res.returncode == 0, res.stderr[-2000:]
    found, batch = digests(alone / "bag"), digests(local_mc / "run_001" / "bag")
    assert {t: found[t] for t in batch} == batch and found["/truth/state"][1] == 201
    assert {t.rsplit("/", 1)[1] for t in set(found) - set(batch)} == {"odometry", "diagnostics", "markers"}
    assert batch != digests(local_mc / "run_000" / "bag")  # a different seed: other messages


def test_a_sweep_on_a_dask_cluster_is_resumed_by_the_local_executor(cluster, tmp_path):
    grid = scenario_with(tmp_path, {"tiny": {"axes": {"rho": {"10km": ["size10km"]}}}})
    out = tmp_path / "sweep"
    args = ["sweep.py", str(grid), "--grid", "tiny", "--runs", "1", "--out", str(out), "--set", "time.duration=60"]
    res = script(*args, "--scheduler", cluster.scheduler_address)
    assert res.returncode == 0, res.stderr[-2000:]
    cells = json.loads((out / "sweep.json").read_text())["cells"]
    assert [c["id"] for c in cells] == ["rho-10km"] and cells[0]["runs_ok"] == 1
    resumed = script(*args, "--resume")
    assert resumed.returncode == 0 and "(1 reused)" in resumed.stderr, resumed.stderr[-2000:]
    assert [c["score"] for c in json.loads((out / "sweep.json").read_text())["cells"]] == [c["score"] for c in cells]


def kill_worker_on_first_attempt(spec: RunSpec):
    """Dask task: on the first attempt of run_000 the run starts, then its worker process is killed (SIGKILL)
    once the run's bag directory exists; later attempts, and the other runs, run normally."""
    marker = spec.out.with_name(spec.out.name + ".killed")
    if marker.exists() or spec.out.name != "run_000":
        return run_task(spec)
    marker.write_text(str(os.getpid()))

    def kill_when_the_bag_exists():
        while not (spec.out / "bag").exists():
            time.sleep(0.01)
        os.kill(os.getpid(), signal.SIGKILL)

    killer = threading.Thread(target=kill_when_the_bag_exists, daemon=True)
    killer.start()
    run_task(spec)
    killer.join()  # the worker dies before this returns


cloudpickle.register_pickle_by_value(sys.modules[__name__])


def test_a_run_whose_worker_is_killed_is_run_again(cluster, local_mc, tmp_path):
    specs = MonteCarlo("leo_radar", tmp_path, 2, overrides=SHORT_PASS[1:]).specs()
    results = run_dask(specs, cluster.scheduler_address, task=kill_worker_on_first_attempt)
    assert sorted(r.spec.out.name for r in results) == ["run_000", "run_001"]
    assert all(r.spec is next(s for s in specs if s.out == r.spec.out) for r in results)  # the caller's specs
    for r in results:
        assert r.ok, (r.code, r.error, r.spec.log.read_text()[-2000:])
        killed = r.spec.out.name == "run_000"
        assert (tmp_path / f"{r.spec.out.name}.killed").is_file() == killed
        # the retry found the killed attempt's partial output and removed it before running again
        assert any("lost with its worker" in note for note in r.reruns) == killed, r.reruns
        assert digests(r.spec.bag) == digests(local_mc / r.spec.out.name / "bag")


def test_resume_keeps_complete_runs_and_makes_the_others(local_mc, tmp_path):
    out = tmp_path / "mc"
    shutil.copytree(local_mc, out)
    kept = (out / "run_000" / "bag" / "metadata.yaml").stat().st_mtime_ns
    (out / "run_001" / "bag" / "metadata.yaml").unlink()  # run 1 as a lost worker or a crash leaves it
    res = script("montecarlo.py", "leo_radar", *RUNS, "--out", str(out), "--json")
    assert res.returncode == 2 and "run_000 already exists" in res.stderr and "--resume" in res.stderr
    res = script("montecarlo.py", "leo_radar", *RUNS, "--out", str(out), "--resume", "--json")
    assert res.returncode == 0, res.stderr[-2000:]
    assert "1 complete runs kept, 1 to run" in res.stderr
    assert (out / "run_000" / "bag" / "metadata.yaml").stat().st_mtime_ns == kept
    assert all(complete(out / f"run_{i:03d}") for i in range(2))
    assert digests(out / "run_001" / "bag") == digests(local_mc / "run_001" / "bag")
    assert json.loads((out / "score.json").read_text())["runs"] == 2
    # another configuration in OUT is not silently mixed in
    res = script(
        "montecarlo.py", "leo_radar", *RUNS, "--set", "sensors.radar.p_detect=0.5", "--out", str(out), "--resume"
    )
    assert res.returncode == 2 and "another configuration" in res.stderr
