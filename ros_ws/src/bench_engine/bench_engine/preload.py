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

import argparse
import importlib
import json
import os
from multiprocessing import process, spawn

from bench_engine import plugins

WARM_ENV = "TRACKING_BENCH_FORK_SERVER"
MAIN_ENV = "TRACKING_BENCH_FORK_MAIN"
"""The path of the command's script, imported by the fork server as multiprocessing's ``__mp_main__``: a forked
run then finds its ``__main__`` in place instead of running the script's imports again (multiprocessing.spawn
prepares a child's ``__main__`` from its path unless it is already that script; the forkserver's own
``"__main__"`` preload never receives the path in Python 3.11). Those imports (a command's scoring, report and
matplotlib) cost about 0.35 s of CPU per run."""
RUN_ENV = "TRACKING_BENCH_FORK_RUN"
"""The arguments of the batch's first run (bench_engine.run's, as JSON), whose objects the fork server builds once
(:func:`warm_run`)."""
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
    """Import what a run imports: the engine, rclpy, the node shells and every registered component, and the
    command's script (MAIN_ENV) as the forked runs' ``__main__``; build the objects of the batch's first run
    (RUN_ENV)."""
    for module in MODULES:
        importlib.import_module(module)
    if os.environ.get(MAIN_ENV):
        import_main(os.environ[MAIN_ENV])
    for group in GROUPS:
        try:
            plugins.registered(group)
        except Exception:  # noqa: BLE001 - a broken plugin is reported by the run that uses it, not here
            pass
    if os.environ.get(RUN_ENV):
        warm_run(json.loads(os.environ[RUN_ENV]))


def warm_run(argv: list[str]) -> None:
    """Build the objects of the run ``argv`` (bench_engine.run's arguments) once, as the run's own validation
    does (launcher.resolve_run): what components cache per process (a star camera's catalogue and k-vector:
    star_tracker.star_camera.pair_table, 0.2-0.3 s a run) is then inherited by every forked run instead of built by
    each. A run whose arguments or scenario fail is left to report it."""
    from bench_engine.cli.options import names  # here: after MODULES, bench_engine.run before numpy (and so below)
    from bench_engine.launcher import resolve_run  # numpy
    from bench_engine.run import add_run_arguments  # sets a run's environment: only in the fork server

    parser = argparse.ArgumentParser(add_help=False, exit_on_error=False)
    add_run_arguments(parser)
    try:
        args, _ = parser.parse_known_args(argv)
        resolve_run(args.scenario, names(args.estimators), args.seed, args.overrides, args.variant)
    except Exception:  # noqa: BLE001 - see the docstring
        pass


def import_main(path: str) -> None:
    """Import the script at ``path`` as ``__mp_main__`` and make it this process's ``__main__`` (what
    multiprocessing does in each child otherwise); a script that fails to import is left to the runs, which
    then import it and report the error as before."""
    process.current_process()._inheriting = True  # as multiprocessing's forkserver around its own main import
    try:
        spawn.import_main_path(path)
    except Exception:  # noqa: BLE001 - see the docstring
        pass
    finally:
        del process.current_process()._inheriting


if os.environ.get(WARM_ENV) == "1":
    warm()
