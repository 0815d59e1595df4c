"""What a run imports, imported once: the local executor's fork server (bench_engine.batch) imports this module
and then forks every run from itself, so a run skips the interpreter start and the imports (numpy, scipy,
rclpy, every registered component) that otherwise take longer than the rest of its start-up.

The warm-up happens only where WARM_ENV is set (batch sets it for its fork server): anywhere else importing this
module loads nothing but the engine (bench_engine imports nothing above itself). In the fork server rclpy is
imported but never initialised, and no Python thread is started (one BLAS thread: bench_engine.run sets it
before numpy loads); the only other threads are the two idle listener threads LTTng-UST starts when rclpy's
tracing library loads, and a forked child has none of them.
"""

from __future__ import annotations

import importlib
import os

from bench_engine import plugins

WARM_ENV = "TRACKING_BENCH_FORK_SERVER"
MODULES = (
    "bench_engine.run",
    "rclpy",
    "bench_engine.bench_node",
    "bench_engine.source_node",
    "bench_engine.stage_node",
    "bench_engine.recorder_node",
    "bench_engine.player_node",
)
"""bench_engine.run first: it sets the environment before numpy loads."""
GROUPS = (
    "node_kinds",
    "sections",
    "codecs",
    "sensors",
    "estimators",
    "dynamics",
    "initialisers",
    "truth_models",
    "metrics",
    "offline",
)


def warm() -> None:
    """Import what a run imports: the engine, rclpy, the node shells and every registered component."""
    for module in MODULES:
        importlib.import_module(module)
    for group in GROUPS:
        try:
            plugins.registered(group)
        except Exception:  # noqa: BLE001 - a broken plugin is reported by the run that uses it, not here
            pass


if os.environ.get(WARM_ENV) == "1":
    warm()
