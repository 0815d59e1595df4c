#!/usr/bin/env python3
"""How consistent can any estimator be early in the leo_radar pass? The filters against the exact posterior.

With 1 deg angles the first scans leave a posterior that is far from Gaussian (curved range shell, ring of
cross-range speeds). This study measures, on identical measurements per seed and at chosen times after the
first scan, the NEES (6 dof; mean over runs, with the runs' 95 % chi-square band) of:
  the scenario's filters (default: its ``ekf`` and ``ukf``), run by the graph's cores in process;
  the batch MAP with its Laplace covariance (Gauss-Newton over every scan; relinearisation.PassBatch);
  the exact posterior's mean and covariance, by adaptive importance sampling
  (tracker_filters/posterior_sampling.py) - the reference any consistent estimator must match.
A Gaussian filter can only be consistent where the Laplace approximation is; where only the sampled
posterior is, consistency needs a sample-based estimator.

Examples:
  .venv/bin/python scripts/leo_posterior_study.py                        # 20 runs, 2/5/10/20/40 s
  .venv/bin/python scripts/leo_posterior_study.py --runs 40 --jobs 2 --times 1,3,10,30,60 --json out.json
  .venv/bin/python scripts/leo_posterior_study.py --estimators ekf_paper,ukf_paper --plot nees.png
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads: one BLAS thread per worker

from tqdm import tqdm  # noqa: E402

from bench_engine.cli.options import add_estimators_option, names  # noqa: E402
from bench_engine.config import ScenarioError, load_scenario  # noqa: E402
from bench_studies.leo_radar.posterior_study import one_run, plot, print_table, summarise  # noqa: E402
from tracker_filters.builders import build_filter_stack  # noqa: E402


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--runs", type=int, default=20, help="seeds 0..runs-1 (default 20)")
    p.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    p.add_argument("--times", default="2,5,10,20,40", help="s after the first scan (default 2,5,10,20,40)")
    add_estimators_option(p, default_text="ekf,ukf; filters of the scenario")
    p.add_argument("--samples", type=int, default=20_000, help="importance samples (default 20000)")
    p.add_argument("--iterations", type=int, default=6, help="adaptive sampling passes (default 6)")
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="scenario override, repeatable (e.g. sensors.radar.sigma_azimuth=4.35e-4)",
    )
    p.add_argument("--json", type=Path, help="write the per-run NEES and the summary here")
    p.add_argument("--plot", type=Path, help="write a plot of mean NEES against time here (PNG)")
    args = p.parse_args(argv)
    try:
        args.times = sorted(float(v) for v in args.times.split(","))
    except ValueError:
        p.error(f"--times must be comma-separated seconds, got {args.times!r}")
    if args.runs < 2 or args.jobs < 1 or args.times[0] <= 0.0:
        p.error("need --runs >= 2, --jobs >= 1 and positive --times")
    args.estimators = names(args.estimators) or ["ekf", "ukf"]
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        cfg = load_scenario("leo_radar", args.overrides)
        for name in args.estimators:
            build_filter_stack(cfg, name)
    except ScenarioError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    jobs = [
        {
            "seed": s,
            "times": args.times,
            "estimators": args.estimators,
            "overrides": args.overrides,
            "samples": args.samples,
            "iterations": args.iterations,
        }
        for s in range(args.runs)
    ]
    with ProcessPoolExecutor(args.jobs) as pool:
        results = list(tqdm(pool.map(one_run, jobs), total=args.runs, unit="run", desc="leo_radar posterior"))
    summary = summarise(results, args.times)
    print_table(summary, args.samples)
    if args.json:
        args.json.write_text(json.dumps({"summary": summary, "runs": results}, indent=1))
    if args.plot:
        plot(summary, args.plot)
        print(f"[posterior study] plot: {args.plot}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
