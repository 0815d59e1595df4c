"""Helpers for the headless graph tests: run the scripts as a user would, read bags with rosbags."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import time
from pathlib import Path

from mcap.reader import make_reader
from rosbags.highlevel import AnyReader

ROOT = Path(__file__).resolve().parent.parent
SCRIPTS = ROOT / "scripts"
SHORT_PASS = ["--set", "time.duration=20"]  # 201 steps from the rise of the leo_radar pass


def script(
    name: str, *args: str, timeout: float = 300, extra_env: dict[str, str] | None = None, **popen
) -> subprocess.CompletedProcess:
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", **(extra_env or {}))
    return subprocess.run(
        [sys.executable, str(SCRIPTS / name), *args], capture_output=True, text=True, timeout=timeout, env=env, **popen
    )


def read_bag(path: Path) -> dict[str, list]:
    """topic -> list of (log_time_ns, decoded message), using the independent rosbags reader."""
    out: dict[str, list] = {}
    with AnyReader([Path(path)]) as reader:
        for conn, t, raw in reader.messages():
            out.setdefault(conn.topic, []).append((t, reader.deserialize(raw, conn.msgtype)))
    return out


def stamp(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def launch_in_background(out: Path, *extra: str) -> subprocess.Popen:
    """A full leo_radar pass in strict lock-step (slow enough to be disturbed in the middle) on a free ROS domain
    (the launcher takes one), its output piped."""
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    return subprocess.Popen(
        [
            sys.executable,
            str(SCRIPTS / "launch.py"),
            "leo_radar",
            "--out",
            str(out),
            "--no-score",
            "--set",
            "time.pacing_window=0",
            *extra,
        ],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def wait_for_stepping(out: Path, proc: subprocess.Popen, timeout: float = 60.0) -> None:
    """Return once the run of ``launch_in_background`` has stepped for a second of wall time."""
    log = out / "logs" / "truth.log"
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        if log.exists() and "stepping" in log.read_text():
            time.sleep(1.0)
            return
        time.sleep(0.1)
    raise AssertionError(f"the run never started stepping: {proc.poll()} {log.read_text() if log.exists() else ''}")


def node_pid(out: Path, node: str) -> int:
    """The pid of node ``node`` of the run writing to ``out`` (its command line names both)."""
    found = subprocess.run(
        ["pgrep", "-f", "--", f"--name {node} --config {out.resolve()}"], capture_output=True, text=True
    )
    return int(found.stdout.split()[0])


def digests(bag: Path) -> dict[str, list]:
    """topic -> [SHA-256 of its messages' CDR bytes in the recorder's order (16 hex digits), message count].

    For comparing two runs made by the same test, on one machine with one set of libraries: the same seed run
    another way (forked or fresh processes, one process, a batch, a retry after a killed node) must give the same
    bytes, since the same code computes them with the same kernels. Never for a run against a stored digest: a
    floating-point result's last bits depend on the CPU's kernels (test_bag_regression.py compares values)."""
    found: dict[str, list] = {}
    with open(next(Path(bag).glob("*.mcap")), "rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages(log_time_order=False):
            entry = found.setdefault(channel.topic, [hashlib.sha256(), 0])
            entry[0].update(message.data)
            entry[1] += 1
    return {topic: [h.hexdigest()[:16], n] for topic, (h, n) in sorted(found.items())}
