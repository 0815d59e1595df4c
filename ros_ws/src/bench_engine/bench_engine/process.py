"""The end of a bench process (a node, a launcher, a Monte Carlo or sweep command): once its bags, scores and
files are written and closed, it exits at once instead of running the interpreter's teardown of every loaded
module (numpy, scipy, rclpy), a large share of a short run's shutdown.

Objects whose own teardown may never return are handed to :func:`keep_until_exit` instead: a single-process
run's ROS nodes, executor and domain (bench_engine.launcher.run_single_process). They stay referenced here, so
no destructor runs while the process goes on (scoring, writing the report), and :func:`exit_now` ends the process
with ``os._exit``, which runs none: the kernel reclaims their memory, threads and sockets."""

from __future__ import annotations

import os
import sys

_KEPT: list[object] = []
"""Objects left to the end of the process (never destroyed in it)."""


def keep_until_exit(*objects: object) -> None:
    """Hold ``objects`` until the process ends: the caller must end it with :func:`exit_now` (every command does),
    not with the interpreter's teardown, which would destroy them."""
    _KEPT.extend(objects)


def exit_now(code: int) -> None:
    """Flush stdout and stderr and end this process with ``code``; call it only when everything is closed."""
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
