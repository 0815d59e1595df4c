#!/usr/bin/env python3
"""Monte Carlo: N seeded runs of a scenario through the ROS 2 graph, every bag kept, metrics over runs.

Run i uses seed SEED0 + i and writes OUT/run_NNN/bag. Up to --jobs runs execute in parallel, each on its
own ROS_DOMAIN_ID (DDS stays on this host). By default each run's nodes share one process (real DDS, one
executor); --multiprocess starts one process per node instead. Metrics are aggregated across runs as in
paper 000 eq. 35 (RMSE per time step over the N runs) and written to OUT/score.json and OUT/report/.

Examples:
  .venv/bin/python scripts/montecarlo.py leo_radar --runs 100 --jobs 2 --out runs/mc
  .venv/bin/python scripts/montecarlo.py leo_radar --runs 10 --filters ukf --set time.duration=120
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path

from tqdm import tqdm

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads: see bench_engine.launcher
LAUNCH = Path(__file__).resolve().parent / "launch.py"


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenario", help="scenario name or YAML path")
    p.add_argument("--runs", type=int, required=True, help="number of Monte Carlo runs")
    p.add_argument("--jobs", type=int, default=2, help="runs in parallel (default 2)")
    p.add_argument("--filters", help="comma-separated filter names (default: the scenario's)")
    p.add_argument("--out", type=Path, default=None, help="output directory (default runs/mc-SCENARIO)")
    p.add_argument("--seed0", type=int, default=1, help="seed of run 0 (run i uses seed0 + i)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="scenario override, repeatable")
    p.add_argument("--variant", help="one of the scenario's named variants")
    p.add_argument("--multiprocess", action="store_true", help="one process per node in every run")
    p.add_argument("--domain-base", type=int, default=None,
                   help="job j uses ROS_DOMAIN_ID domain-base + j (default: each run takes a free domain)")
    p.add_argument("--json", action="store_true", help="print the aggregated scores as JSON")
    args = p.parse_args(argv)
    if args.runs < 1 or args.jobs < 1:
        p.error("--runs and --jobs must be >= 1")
    if args.domain_base is not None and args.domain_base + args.jobs - 1 > 101:
        p.error("--domain-base + --jobs - 1 must be <= 101 (ROS_DOMAIN_ID range)")
    return args


def launch_command(args: argparse.Namespace, i: int, domain: int | None) -> list[str]:
    cmd = [sys.executable, str(LAUNCH), args.scenario, "--seed", str(args.seed0 + i), "--out",
           str(args.out / f"run_{i:03d}"), "--no-score"]
    if domain is not None:
        cmd += ["--domain-id", str(domain)]
    if args.filters:
        cmd += ["--filters", args.filters]
    if args.variant:
        cmd += ["--variant", args.variant]
    if not args.multiprocess:
        cmd.append("--single-process")
    for o in args.overrides:
        cmd += ["--set", o]
    return cmd


def validate_first(args: argparse.Namespace) -> None:
    """Fail before starting N runs when the scenario or an override is wrong."""
    from bench_engine.config import ScenarioError
    from bench_engine.launcher import prepare_run
    try:
        filters = args.filters.split(",") if args.filters else None
        prepare_run(args.scenario, args.out / "validate", filters, args.seed0, args.overrides, args.variant)
    except ScenarioError as err:
        print(f"error: {err}", file=sys.stderr)
        sys.exit(2)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    args.out = args.out or Path(f"runs/mc-{Path(args.scenario).stem}")
    args.out.mkdir(parents=True, exist_ok=True)
    validate_first(args)
    free_domains = (list(range(args.domain_base, args.domain_base + args.jobs)) if args.domain_base is not None
                    else [None] * args.jobs)
    failures: list[str] = []
    started = time.monotonic()

    def one(i: int) -> tuple[int, int]:
        domain = free_domains.pop()
        try:
            with open(args.out / f"run_{i:03d}.log", "w") as log:
                return i, subprocess.run(launch_command(args, i, domain), stdout=log, stderr=subprocess.STDOUT).returncode
        finally:
            free_domains.append(domain)

    with ThreadPoolExecutor(args.jobs) as pool, tqdm(total=args.runs, unit="run", desc=args.scenario) as bar:
        for fut in as_completed([pool.submit(one, i) for i in range(args.runs)]):
            i, code = fut.result()
            if code != 0:
                failures.append(f"run {i} (exit {code}, log {args.out / f'run_{i:03d}.log'})")
            bar.update()
    wall = time.monotonic() - started
    print(f"[montecarlo] {args.runs} runs in {wall:.0f} s ({60 * args.runs / wall:.1f} runs/min)", file=sys.stderr)
    bags = [args.out / f"run_{i:03d}" / "bag" for i in range(args.runs)
            if (args.out / f"run_{i:03d}" / "bag" / "metadata.yaml").is_file()]
    if not bags:
        print("error: no run produced a bag", file=sys.stderr)
        return 1
    from bench_eval.report import write_report
    from bench_eval.scoring import print_summary, score_bags
    scored, series = score_bags(bags, with_series=True)
    scored["runs_per_minute"] = round(60 * args.runs / wall, 2)
    (args.out / "score.json").write_text(json.dumps(scored, indent=1))
    report = write_report(args.out / "report", {scored["scenario"]: scored["filters"]},
                          {scored["scenario"]: series} if series else {})
    print(json.dumps(scored, indent=1) if args.json else print_summary(scored))
    print(f"[montecarlo] report: {report}", file=sys.stderr)
    for f in failures:
        print(f"[montecarlo] failed: {f}", file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
