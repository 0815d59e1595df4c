"""Helpers for the headless graph tests: run the scripts as a user would, read bags with rosbags."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from rosbags.highlevel import AnyReader

ROOT = Path(__file__).resolve().parent.parent
SCRIPTS = ROOT / "scripts"
SHORT_PASS = ["--set", "time.duration=20"]  # 201 steps from the rise of the leo_radar pass


def script(name: str, *args: str, timeout: float = 300, extra_env: dict[str, str] | None = None,
           **popen) -> subprocess.CompletedProcess:
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", **(extra_env or {}))
    return subprocess.run([sys.executable, str(SCRIPTS / name), *args], capture_output=True, text=True,
                          timeout=timeout, env=env, **popen)


def read_bag(path: Path) -> dict[str, list]:
    """topic -> list of (log_time_ns, decoded message), using the independent rosbags reader."""
    out: dict[str, list] = {}
    with AnyReader([Path(path)]) as reader:
        for conn, t, raw in reader.messages():
            out.setdefault(conn.topic, []).append((t, reader.deserialize(raw, conn.msgtype)))
    return out


def stamp(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
