"""The one Monte Carlo runner: many seeded runs of a scenario through the graph, in parallel, every bag kept.
Used by montecarlo.py, sweep.py, demo.py and the studies' scripts.

A run (bench_engine.batch_run; its RunSpec, RunResult, run_one, complete and crosstalk are imported from here
too) is one launcher process on a ROS domain of its own, forked from a fork server that has imported what a
run needs; a run that received messages from a foreign graph on its domain is set aside and run again.

Executors: local threads, ``jobs`` runs at a time on this host (the default), or a Dask distributed cluster
(``scheduler``: an address, or ``"local"`` for a LocalCluster of ``jobs`` worker processes; see
bench_engine.executors). Either way a run is the same subprocess, and its bag lands in its output directory.
Either way a run one of whose nodes was killed (by a signal: the OOM killer, an operator) is set aside and run
again (batch_run.NODE_RETRIES times at most, a line naming the run and the node as each retry starts;
RunResult.killed and RunResult.reruns tell them afterwards).
"""

from __future__ import annotations

import shutil
import sys
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path

from tqdm import tqdm

from bench_engine import yamlio
from bench_engine.batch_run import RunResult, RunSpec, complete, crosstalk, recorded_steps, run_one
from bench_engine.config import ScenarioError
from bench_engine.scenario import coerce_scenario
from bench_engine.views import SWITCH as VIEWS_SWITCH


def _comparable(cfg: dict) -> dict:
    """A resolved scenario as a run records it (bench_engine.scenario.coerce_scenario) without the views switch:
    the views change no estimate, and a batch sets the switch in its runs (RunSpec.standard_views), not in the
    configuration its caller expects."""
    return {k: v for k, v in coerce_scenario(cfg).items() if k != VIEWS_SWITCH}


def reusable_run(out: Path, expected: dict, resume: bool) -> bool:
    """Whether ``out`` holds a complete run of the resolved scenario ``expected`` (seed included) to keep
    instead of running it again (``resume``). An incomplete run there (a lost worker, an interrupted batch) is
    removed to be run again. Raises ScenarioError if ``out`` exists without ``resume``, or holds a run of
    another configuration or with foreign messages."""
    if not out.exists():
        return False
    if not resume:
        raise ScenarioError(f"{out} already exists: choose another --out, remove it, or give --resume")
    if not complete(out):
        shutil.rmtree(out)
        return False
    if _comparable(yamlio.load((out / "bag" / "run_config.yaml").read_text())["scenario"]) != _comparable(expected):
        raise ScenarioError(f"{out} was run with another configuration or seed: remove it or choose another --out")
    if crosstalk(out / "bag", recorded_steps(out / "bag")):
        raise ScenarioError(f"{out} holds messages of another graph: remove it to run it again")
    return True


def run_batch(
    specs: list[RunSpec],
    jobs: int = 2,
    domains: list[int] | None = None,
    desc: str = "runs",
    on_done: Callable[[RunResult], None] | None = None,
    scheduler: str | None = None,
    retries: int = 2,
) -> list[RunResult]:
    """Run every spec, ``jobs`` at a time with a progress bar; ``domains`` (one per job) pins the ROS domains,
    else each run reserves a free one. ``on_done`` is called as each run ends (in the caller's thread).
    ``scheduler``: run on a Dask cluster instead (an address or ``"local"``; bench_engine.executors), each
    run retried up to ``retries`` times if it raises or its worker is lost. Either executor runs again a run
    whose node was killed (batch_run.run_one). Runs are made without the standard views unless their spec asks
    for them (RunSpec.standard_views)."""
    if scheduler is not None:
        from bench_engine.executors import run_dask  # dask.distributed: only with a scheduler

        return run_dask(specs, scheduler, jobs, desc, on_done, retries)
    free = list(domains) if domains is not None else [None] * jobs
    if len(free) < jobs:
        raise ValueError(f"{jobs} jobs need {jobs} domains, got {len(free)}")

    def retrying(note: str) -> None:
        tqdm.write(f"[batch] {note}", file=sys.stderr)

    def one(spec: RunSpec) -> RunResult:
        domain = free.pop()
        try:
            return run_one(spec, domain, retrying)
        finally:
            free.append(domain)

    results = []
    with ThreadPoolExecutor(jobs) as pool, tqdm(total=len(specs), unit="run", desc=desc) as bar:
        for future in as_completed([pool.submit(one, s) for s in specs]):
            result = future.result()
            results.append(result)
            if on_done is not None:
                on_done(result)
            bar.update()
    return results
