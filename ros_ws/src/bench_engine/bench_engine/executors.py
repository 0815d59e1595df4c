"""The Dask executor of the one Monte Carlo runner (bench_engine.batch): runs on a dask.distributed cluster.

Each task is one whole run: the same subprocess the local executor starts (``python -m bench_engine.run``),
on the host of the worker that takes it, with DDS kept on that host (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST)
and a free ROS domain of that host (the run reserves it: bench_engine.domains). Its bag is written to its
output directory, an absolute path that must be the same on every host (a shared file system).

A worker lost in the middle of a run: its run process dies with it (PR_SET_PDEATHSIG), the scheduler gives the
task to another worker (up to ``distributed.scheduler.allowed-failures`` lost workers), and the new attempt
removes the incomplete output of the lost one before it starts. A task that raises is retried ``retries``
times. A run whose node was killed is run again by the task itself (bench_engine.batch_run.run_one), a line
on the worker's stderr as each retry starts. bench_engine.batch imports this module (and dask) only when a
scheduler is given.
"""

from __future__ import annotations

import ctypes
import os
import shutil
import signal
import sys
from collections.abc import Callable
from dataclasses import replace
from typing import Any

from dask.distributed import Client, LocalCluster, as_completed
from tqdm import tqdm

from bench_engine.batch_run import RunResult, RunSpec, complete, run_one

RUN_ENV = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "OPENBLAS_NUM_THREADS": "1"}
PR_SET_PDEATHSIG = 1


def _die_with_worker() -> None:
    """In the run's process, before exec: be killed when the worker process (its parent) dies."""
    ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)


def run_task(spec: RunSpec) -> RunResult:
    """One run on this worker's host (the Dask task). A complete bag already in OUT (an earlier attempt that
    finished before its worker was lost) is kept; an incomplete one is removed and the run made again."""
    notes = []
    if spec.out.exists():
        if complete(spec.out):
            return RunResult(spec, 0, [f"{spec.out}: kept the complete run of an earlier attempt"])
        shutil.rmtree(spec.out)
        notes.append(f"{spec.out}: an earlier attempt was lost with its worker; ran it again")
    result = run_one(
        spec,
        None,
        lambda note: print(f"[batch] {note}", file=sys.stderr, flush=True),
        env={**os.environ, **RUN_ENV},
        preexec_fn=_die_with_worker,
    )
    result.reruns = notes + result.reruns
    return result


def connect(scheduler: str, jobs: int):
    """A dask.distributed Client: of the scheduler at ``scheduler``, or of a new LocalCluster of ``jobs``
    single-threaded worker processes on 127.0.0.1 when ``scheduler`` is ``"local"``."""
    if scheduler == "local":
        cluster = LocalCluster(
            n_workers=jobs, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
        )
        client = Client(cluster)
        client.bench_cluster = cluster
        return client
    return Client(scheduler)


def close(client) -> None:
    cluster = getattr(client, "bench_cluster", None)
    client.close()
    if cluster is not None:
        cluster.close()


def run_dask(
    specs: list[RunSpec],
    scheduler: str,
    jobs: int = 2,
    desc: str = "runs",
    on_done: Callable[[RunResult], None] | None = None,
    retries: int = 2,
    task: Callable[[RunSpec], RunResult] = run_task,
) -> list[RunResult]:
    """Run every spec as a task on the cluster (``connect``), with a progress bar; results in the order they
    end, each carrying the caller's own spec object. A run whose task failed for good (it raised more than
    ``retries`` times, or lost too many workers) is a failed RunResult naming the error."""
    client = connect(scheduler, jobs)
    results = []
    try:
        futures = {
            client.submit(
                task,
                replace(s, out=s.out.resolve()),
                retries=retries,
                pure=False,
                key=f"run-{i:05d}-{s.out.name}-{os.urandom(4).hex()}",
            ): s
            for i, s in enumerate(specs)
        }
        with tqdm(total=len(specs), unit="run", desc=desc) as bar:
            for future in as_completed(futures):
                spec = futures[future]
                try:
                    result = future.result()
                except Exception as err:  # the task raised on every attempt, or KilledWorker
                    result = RunResult(spec, 1, error=f"{type(err).__name__}: {err}")
                result.spec = spec
                results.append(result)
                if on_done is not None:
                    on_done(result)
                bar.update()
    finally:
        close(client)
    return results


def map_dask(
    fn: Callable[[Any], Any], items: list, scheduler: str, jobs: int = 2, desc: str = "tasks", retries: int = 2
) -> list:
    """``[fn(item) for item in items]`` on the cluster at ``scheduler`` (:func:`connect`), in order, with a
    progress bar; ``fn`` and the items must pickle, and any path in an item must be the same on every host (a
    shared file system). A task that raises is retried ``retries`` times, then its error is raised here."""
    client = connect(scheduler, jobs)
    try:
        futures = [
            client.submit(fn, item, retries=retries, pure=False, key=f"{desc}-{i:05d}-{os.urandom(4).hex()}")
            for i, item in enumerate(items)
        ]
        with tqdm(total=len(items), unit="task", desc=desc) as bar:
            for _ in as_completed(futures):
                bar.update()
        return [f.result() for f in futures]
    finally:
        close(client)
