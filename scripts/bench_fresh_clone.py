#!/usr/bin/env python3
"""The two commands as a new user meets them: ``make demo`` and ``make test`` timed from fresh clones.

Each run clones the repository (its committed ``--rev``, default HEAD) into a new scratch directory, so nothing
of this checkout is reused: no virtual environment, no bench_msgs build, no bytecode. It then times the command
end to end, and takes the setup's share from its own ``[setup] ready: ... (N s)`` line and the tests' outcome
from pytest's summary line. The package caches of uv and pip (in the user's home) are reused unless
``--cold-cache`` gives every clone empty ones, as on a machine that never installed the wheels (then the
download speed of the network is in the figure).

Nothing is asserted: the figures are printed (a table), and the exit status is 1 when a command failed.

Examples:
  .venv/bin/python scripts/bench_fresh_clone.py --demo                 # one fresh-clone make demo
  .venv/bin/python scripts/bench_fresh_clone.py --test-runs 5          # five fresh-clone make test, in turn
  .venv/bin/python scripts/bench_fresh_clone.py --demo --test-runs 1 --cold-cache
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SETUP_READY = re.compile(r"\[setup\] ready: .* \((\d+) s\)")
PYTEST_SUMMARY = re.compile(r"^=*\s*((?:\d+ \w+(?:, )?)+) in [\d.]+s", re.MULTILINE)


@dataclass(frozen=True)
class Timing:
    """One fresh-clone run of a make target."""

    target: str
    wall_s: float
    setup_s: float | None
    outcome: str
    ok: bool


def _clone(rev: str, where: Path) -> Path:
    """A new clone of this repository at ``rev`` in ``where``/bench (no hard links: nothing shared)."""
    dest = where / "bench"
    subprocess.run(["git", "clone", "-q", "--no-hardlinks", str(ROOT), str(dest)], check=True)
    subprocess.run(["git", "-C", str(dest), "checkout", "-q", rev], check=True)
    return dest


def _environment(scratch: Path, cold_cache: bool) -> dict[str, str]:
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    env.pop("VIRTUAL_ENV", None)
    if cold_cache:
        env.update(UV_CACHE_DIR=str(scratch / "uv-cache"), PIP_CACHE_DIR=str(scratch / "pip-cache"))
    return env


def time_target(target: str, rev: str, cold_cache: bool, keep: bool) -> Timing:
    """Clone, then run ``make TARGET`` in the clone; its wall time, setup time and outcome."""
    scratch = Path(tempfile.mkdtemp(prefix="bench-fresh-"))
    try:
        clone = _clone(rev, scratch)
        start = time.monotonic()
        result = subprocess.run(
            ["make", target], cwd=clone, env=_environment(scratch, cold_cache), capture_output=True, text=True
        )
        wall = time.monotonic() - start
        (scratch / f"make-{target}.log").write_text(result.stdout + result.stderr)
        setup = SETUP_READY.search(result.stdout + result.stderr)
        summary = PYTEST_SUMMARY.findall(result.stdout)
        outcome = summary[-1] if summary else ("ok" if result.returncode == 0 else f"exit {result.returncode}")
        if result.returncode != 0:
            print(
                f"[fresh] make {target} failed (exit {result.returncode}); log: {scratch}/make-{target}.log",
                file=sys.stderr,
            )
            keep = True
        return Timing(target, wall, float(setup.group(1)) if setup else None, outcome, result.returncode == 0)
    finally:
        if not keep:
            shutil.rmtree(scratch, ignore_errors=True)


def _machine() -> str:
    model = (
        next(
            (
                line.split(":", 1)[1].strip()
                for line in Path("/proc/cpuinfo").read_text().splitlines()
                if line.startswith("model name")
            ),
            "unknown CPU",
        )
        if Path("/proc/cpuinfo").is_file()
        else "?"
    )
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    return f"{os.cpu_count()} CPUs, {model}, load average {load} at the start"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        epilog=__doc__.split("Examples:")[1],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--demo", action="store_true", help="time one fresh-clone `make demo`")
    p.add_argument("--test-runs", type=int, default=0, metavar="N", help="time N fresh-clone `make test`, in turn")
    p.add_argument("--rev", default="HEAD", help="the commit to clone (default HEAD)")
    p.add_argument("--cold-cache", action="store_true", help="empty uv and pip caches for every clone")
    p.add_argument("--keep", action="store_true", help="keep the scratch clones and their logs")
    args = p.parse_args(argv)
    if not args.demo and args.test_runs < 1:
        p.error("nothing to time: give --demo and/or --test-runs N (N >= 1)")
    rev = subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", "--short=12", args.rev], capture_output=True, text=True, check=True
    ).stdout.strip()
    print(f"commit {rev}; {_machine()}; package caches {'cold' if args.cold_cache else 'warm'}")
    print("| command | run | wall [s] | of which setup [s] | outcome |\n|---|---|---|---|---|", flush=True)
    targets = (["demo"] if args.demo else []) + ["test"] * args.test_runs
    timings = []
    for i, target in enumerate(targets):
        t = time_target(target, rev, args.cold_cache, args.keep)
        timings.append(t)
        run = sum(1 for x in targets[: i + 1] if x == target)
        setup = "n/a" if t.setup_s is None else f"{t.setup_s:.0f}"
        print(f"| make {target} | {run} | {t.wall_s:.0f} | {setup} | {t.outcome} |", flush=True)
    return 0 if all(t.ok for t in timings) else 1


if __name__ == "__main__":
    sys.exit(main())
