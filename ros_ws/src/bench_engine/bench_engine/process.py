"""The end of a bench process (a node, a launcher, a Monte Carlo or sweep command): once its bags, scores and
files are written and closed, it exits at once instead of running the interpreter's teardown of every loaded
module (numpy, scipy, rclpy), a large share of a short run's shutdown."""
from __future__ import annotations

import os
import sys


def exit_now(code: int) -> None:
    """Flush stdout and stderr and end this process with ``code``; call it only when everything is closed."""
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
