#!/usr/bin/env python3
"""Run a scenario through the ROS 2 graph, record a rosbag2-style MCAP bag, and print its score.

Examples:
  .venv/bin/python scripts/launch.py leo_radar
  .venv/bin/python scripts/launch.py leo_radar --filters ukf --seed 7 --out runs/ukf7
  .venv/bin/python scripts/launch.py leo_radar --set sensors.radar.p_detect=1.0 --single-process
  .venv/bin/python scripts/launch.py leo_radar --variant table3_angles

DDS stays on this host (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST); each run uses its own ROS_DOMAIN_ID.
Exit code: 0 on success, 1 if a node failed, 2 for a bad scenario/parameter, 128+N if interrupted by signal N.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads: see bench_engine.launcher

from bench_engine.config import ScenarioError, available_scenarios  # noqa: E402
from bench_engine.launcher import prepare_run, run_graph  # noqa: E402


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenario", help=f"scenario name ({', '.join(available_scenarios())}) or a YAML path")
    p.add_argument("--filters", help="comma-separated filter names (default: the scenario's default_filters)")
    p.add_argument("--seed", type=int, help="random seed of the sensors (default: the scenario's seed)")
    p.add_argument("--out", default=None, help="output directory (default: runs/SCENARIO-TIMESTAMP)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario key, e.g. --set sensors.radar.sigma_range=10 (repeatable)")
    p.add_argument("--variant", help="apply one of the scenario's named variants")
    p.add_argument("--single-process", action="store_true",
                   help="run every node in this one process, pinned to one CPU (the fastest mode)")
    p.add_argument("--no-pin", action="store_true",
                   help="with --single-process: let the process's threads use every CPU (slower, see "
                        "bench_engine.launcher.pin_to_one_cpu)")
    p.add_argument("--domain-id", type=int, default=None,
                   help="ROS_DOMAIN_ID of this run (default: the first one no other bench run holds)")
    p.add_argument("--executor", choices=["events", "single"], default="events",
                   help="rclpy executor (events = rclpy.experimental.EventsExecutor, the fastest)")
    p.add_argument("--no-score", action="store_true", help="do not score the bag after the run")
    p.add_argument("--json", action="store_true", help="print the score as JSON")
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    out = Path(args.out or f"runs/{Path(args.scenario).stem}-{time.strftime('%Y%m%d-%H%M%S')}")
    filters = [f.strip() for f in args.filters.split(",") if f.strip()] if args.filters else None
    try:
        plan = prepare_run(args.scenario, out, filters, args.seed, args.overrides, args.variant,
                           extra={"executor": args.executor})
    except ScenarioError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    started = time.monotonic()
    code = run_graph(plan, args.domain_id, args.single_process, args.executor, pin=not args.no_pin)
    wall = time.monotonic() - started
    timing = plan.out / "timing.json"
    if timing.exists():
        t = json.loads(timing.read_text())
        sim = (t["steps"] - 1) * plan.run["scenario"]["time"]["dt"]
        print(f"[launch] wall {wall:.1f} s (start-up {t['startup_s']:.1f} s, stepping {t['stepping_s']:.1f} s: "
              f"{sim / max(t['stepping_s'], 1e-9):.0f}x real time); bag {plan.bag_dir}", file=sys.stderr)
    if code != 0 or args.no_score:
        return code
    from bench_eval.scoring import score_run
    print(score_run(plan.out, args.json))
    return 0


if __name__ == "__main__":
    sys.exit(main())
