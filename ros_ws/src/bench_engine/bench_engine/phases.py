"""Phase timestamps of a run, for scripts/bench_phases.py: off unless ``TRACKING_BENCH_PHASES`` names a file.

Each process of a run (launcher, node processes, batch workers) appends one JSON line per event to that file:
``{"t": wall time [s], "event": name, "who": process role, "run": run output directory, "pid": pid}``. Lines
are short and the file is opened in append mode, so concurrent processes never interleave within a line.
Events are a handful per process and run; with the variable unset ``mark`` returns at once.
"""

from __future__ import annotations

import json
import os
import time

ENV = "TRACKING_BENCH_PHASES"


def enabled() -> bool:
    return bool(os.environ.get(ENV))


def process_start_time() -> float:
    """Wall time at which this process started (Linux: /proc; 10 ms resolution), else now."""
    try:
        with open("/proc/self/stat") as f:
            ticks = int(f.read().rsplit(")", 1)[1].split()[19])
        with open("/proc/uptime") as f:
            uptime = float(f.read().split()[0])
        return time.time() - (uptime - ticks / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError):
        return time.time()


def mark(event: str, who: str, run: str | os.PathLike | None = None, t: float | None = None, **extra) -> None:
    """Record ``event`` of process role ``who`` (e.g. ``launcher``, a node name) of run ``run`` at ``t``
    (default now), if phase recording is on."""
    path = os.environ.get(ENV)
    if not path:
        return
    record = {
        "t": time.time() if t is None else t,
        "event": event,
        "who": who,
        "run": str(run) if run is not None else None,
        "pid": os.getpid(),
        **extra,
    }
    with open(path, "a") as f:
        f.write(json.dumps(record) + "\n")


def mark_process_start(who: str, run: str | os.PathLike | None = None) -> None:
    """Record when this process's interpreter started (``proc_start``) and that its imports are done
    (``imported``, now)."""
    if enabled():
        mark("proc_start", who, run, t=process_start_time())
        mark("imported", who, run)


def read(path: str | os.PathLike) -> list[dict]:
    """Every record of a phase file, in time order."""
    with open(path) as f:
        records = [json.loads(line) for line in f if line.strip()]
    return sorted(records, key=lambda r: r["t"])
