#!/usr/bin/env python3
"""Graph speed: sim-time / wall-time ratio of a full run (truth + sensors + estimators + recorder).

Runs the scenario through launch.py in each process mode and prints start-up time (process start to the
first step: discovery and readiness barrier) separately from the stepping time, and the ratio of simulated
time to stepping wall time. Nothing is asserted: these are measurements.

Example:
  .venv/bin/python scripts/bench_graph.py                       # leo_radar, 420 s pass at 10 Hz, EKF + UKF
  .venv/bin/python scripts/bench_graph.py --repeat 3 --modes single-process
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from bench_engine import yamlio

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads: see bench_engine.launcher
LAUNCH = Path(__file__).resolve().parent / "launch.py"
MODES = {
    "multi-process": [],
    "single-process": ["--single-process"],
    "single-process-unpinned": ["--single-process", "--no-pin"],
}


def one_run(scenario: str, mode: str, estimators: str, domain: int, extra: list[str]) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        cmd = [
            sys.executable,
            str(LAUNCH),
            scenario,
            "--out",
            str(out),
            "--domain-id",
            str(domain),
            "--no-score",
            "--estimators",
            estimators,
            *MODES[mode],
            *extra,
        ]
        res = subprocess.run(cmd, capture_output=True, text=True)
        if res.returncode != 0:
            raise RuntimeError(f"{mode} run failed:\n{res.stderr[-2000:]}")
        timing = json.loads((out / "timing.json").read_text())
        run = yamlio.load((out / "run_config.yaml").read_text())
    timing["sim_s"] = (timing["steps"] - 1) * run["scenario"]["time"]["dt"]
    return timing


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scenario", default="leo_radar")
    p.add_argument("--estimators", default="ekf,ukf")
    p.add_argument("--repeat", type=int, default=1, help="runs per mode (the median is printed)")
    p.add_argument("--modes", default=",".join(MODES), help=f"comma-separated subset of {list(MODES)}")
    p.add_argument("--domain-id", type=int, default=90)
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    args = p.parse_args(argv)
    extra = [a for o in args.overrides for a in ("--set", o)]
    print(f"{args.scenario} with {args.estimators} + recorder; {args.repeat} run(s) per mode, median")
    print(
        f"{'mode':16s} {'steps':>6s} {'sim [s]':>8s} {'start-up [s]':>12s} {'stepping [s]':>12s} "
        f"{'steps/s':>8s} {'sim/wall':>9s}"
    )
    for mode in args.modes.split(","):
        runs = [one_run(args.scenario, mode, args.estimators, args.domain_id, extra) for _ in range(args.repeat)]
        startup = statistics.median(r["startup_s"] for r in runs)
        stepping = statistics.median(r["stepping_s"] for r in runs)
        steps, sim = runs[0]["steps"], runs[0]["sim_s"]
        print(
            f"{mode:16s} {steps:6d} {sim:8.1f} {startup:12.2f} {stepping:12.2f} {steps / stepping:8.0f} "
            f"{sim / stepping:8.0f}x"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
