"""What a run imports, imported once: the local executor's fork server (bench_engine.batch) imports this module
and then forks every run from itself, so a run skips the interpreter start and the imports (numpy, scipy,
rclpy, every registered component) that otherwise take longer than the rest of its start-up.

Importing this module has no other effect: rclpy is imported but never initialised here, and no Python thread
is started (one BLAS thread: bench_engine.run sets it before numpy loads). The only threads are the two idle
listener threads LTTng-UST starts when rclpy's tracing library loads; a forked child has none of them.
"""
from __future__ import annotations

import bench_engine.run  # noqa: F401  (first: sets the environment before numpy loads)
import rclpy  # noqa: F401
from bench_engine import bench_node, player_node, plugins, recorder_node, source_node, stage_node  # noqa: F401

GROUPS = ("node_kinds", "sections", "codecs", "sensors", "estimators", "dynamics", "initialisers", "truth_models",
          "metrics", "offline")


def _import_registered() -> None:
    for group in GROUPS:
        try:
            plugins.registered(group)
        except Exception:  # noqa: BLE001 - a broken plugin is reported by the run that uses it, not here
            pass


_import_registered()
