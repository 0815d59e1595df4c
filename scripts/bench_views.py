#!/usr/bin/env python3
"""What the standard views cost: ``launch.py SCENARIO`` as a user runs it, with its views and without them.

Alternates the default run (every estimate and the truth also as Odometry, poses, diagnostics and markers:
bench_engine.views) with the same run under ``--set standard_views=false``, PAIRS times, so both meet the same
machine load, and prints each run's wall time (process start to exit, scoring included unless ``--no-score``),
its stepping time (the truth's first step to its last: timing.json), the messages in its bag, and the medians with
the views' overhead (median with / median without - 1). Nothing is asserted: these are measurements.

Example:
  .venv/bin/python scripts/bench_views.py                        # leo_radar, 5 pairs, scored as by default
  .venv/bin/python scripts/bench_views.py --pairs 3 --no-score
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads: see bench_engine.launcher

from mcap.reader import make_reader  # noqa: E402

LAUNCH = Path(__file__).resolve().parent / "launch.py"
MODES = {"with views": [], "without": ["--set", "standard_views=false"]}


def bag_messages(bag: Path) -> int:
    """The number of messages in a run's bag (its MCAP summary)."""
    with next(bag.glob("*.mcap")).open("rb") as f:
        return make_reader(f).get_summary().statistics.message_count


def one_run(scenario: str, extra: list[str]) -> dict:
    """One launch.py run: its wall time, stepping time and bag size."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        cmd = [sys.executable, str(LAUNCH), scenario, "--out", str(out), *extra]
        start = time.perf_counter()
        done = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - start
        if done.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd[1:])} failed:\n{done.stderr[-2000:]}")
        stepping = json.loads((out / "timing.json").read_text())["stepping_s"]
        return {"wall_s": wall, "stepping_s": stepping, "messages": bag_messages(out / "bag")}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scenario", default="leo_radar")
    p.add_argument("--pairs", type=int, default=5, help="runs of each, alternated (default 5)")
    p.add_argument("--no-score", action="store_true", help="time the runs without their scoring")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    args = p.parse_args(argv)
    if args.pairs < 1:
        p.error("--pairs must be at least 1")
    extra = [a for o in args.overrides for a in ("--set", o)] + (["--no-score"] if args.no_score else [])
    runs: dict[str, list[dict]] = {mode: [] for mode in MODES}
    print(f"launch.py {args.scenario}{' --no-score' if args.no_score else ''}: {args.pairs} alternated pairs")
    print("| pair | views | wall [s] | stepping [s] | bag messages |\n|---|---|---|---|---|", flush=True)
    for pair in range(1, args.pairs + 1):
        for mode, flags in MODES.items():
            r = one_run(args.scenario, extra + flags)
            runs[mode].append(r)
            print(f"| {pair} | {mode} | {r['wall_s']:.2f} | {r['stepping_s']:.2f} | {r['messages']} |", flush=True)
    med = {
        mode: {k: statistics.median(r[k] for r in rs) for k in ("wall_s", "stepping_s")} for mode, rs in runs.items()
    }
    on, off = med["with views"], med["without"]
    print(
        f"\nmedian wall {on['wall_s']:.2f} s with the views, {off['wall_s']:.2f} s without: "
        f"{100 * (on['wall_s'] / off['wall_s'] - 1):+.0f} %; "
        f"stepping {on['stepping_s']:.2f} s against {off['stepping_s']:.2f} s: "
        f"{100 * (on['stepping_s'] / off['stepping_s'] - 1):+.0f} %"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
