#!/usr/bin/env python3
"""How far is every estimator from the best the data allow? RMSE next to the scenario's bounds (scoring.bounds).

Per case (the scenario, or every cell of one of its sweep grids), N seeded runs of the case's filters in
process (bench_engine.inprocess: the graph's cores and seeds, without ROS), scored by bench_eval.scoring with
the scenario's bounds (bench_eval/bounds.py: e.g. the posterior CRB with the truth's dynamics). Prints one
Markdown table: per case and estimator, for position and velocity, the efficiency (mean over the summarised
steps of RMSE^2 / bound)^-1/2 (1 = the best possible; a bound is a lower bound, so efficiency > 1 only by Monte
Carlo error or where the bound's assumptions fail) and, at the last step, the RMSE over runs next to the square
root of the bound.
With --out, each case's report (the study's tables and figures, √bound dashed) goes to OUT/CASE/.

Examples:
  .venv/bin/python scripts/bounds.py leo_radar --runs 10
  .venv/bin/python scripts/bounds.py formation_pf --runs 10 --variant j2_truth
  .venv/bin/python scripts/bounds.py formation_pf --runs 10 --estimators pf,ukf \
      --set 'filters.ukf={type: ukf, dynamics: {model: cw, sigma_accel: 0.0}}'
  .venv/bin/python scripts/bounds.py formation_cqkf --grid tables --runs 2 --out runs/bounds-cqkf
"""

from __future__ import annotations

import argparse
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads: one BLAS thread per worker

from bench_engine.cli.options import add_estimators_option, names  # noqa: E402
from bench_engine.config import ScenarioError, load_scenario, select_variant  # noqa: E402
from bench_eval.inprocess_runs import bag_data  # noqa: E402
from bench_eval.report import fmt, write_report  # noqa: E402
from bench_eval.scoring import score_bags  # noqa: E402
from bench_eval.sweep import load_grid  # noqa: E402


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenario", help="registered scenario name or YAML path")
    p.add_argument("--runs", type=int, default=10, help="seeds seed0..seed0+runs-1 per case (default 10)")
    p.add_argument("--seed0", type=int, default=1, help="first seed (default 1)")
    p.add_argument("--variant", default="", help="comma-separated variants (not with --grid)")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="scenario override (repeatable), e.g. --set 'filters.ukf.dynamics.sigma_accel=0.0'",
    )
    p.add_argument("--grid", help="every cell of this sweep grid of the scenario (scripts/sweep.py's grids)")
    add_estimators_option(p)
    p.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    p.add_argument("--out", type=Path, help="write each case's report (Markdown + PNG) under this directory")
    return p.parse_args(argv)


def _run(job: tuple[dict, list[str] | None, int]):
    cfg, estimators, seed = job
    return bag_data(cfg, estimators, seed)


def table_rows(case: str, scored: dict) -> list[str]:
    rows = []
    for est, block in scored.items():
        for bound, b in (block.get("bounds") or {}).items():
            cells = [
                f"{fmt(b[g]['efficiency'])} ({fmt(b[g]['final_rmse'])} / {fmt(b[g]['final_sqrt_bound'])})"
                for g in ("position", "velocity")
                if g in b
            ]
            rows.append(f"| {case} | {est} | {bound} | " + " | ".join(cells) + " |")
    return rows


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        if args.grid:
            cases = [(c.id, c.cfg) for c in load_grid(args.scenario, args.grid, args.set).cells]
        else:
            cases = [(args.variant or "default", select_variant(load_scenario(args.scenario, args.set), args.variant))]
    except ScenarioError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    estimators = names(args.estimators)
    seeds = range(args.seed0, args.seed0 + args.runs)
    print(f"{args.scenario}: {len(cases)} case(s) x {args.runs} runs (seeds {seeds[0]}..{seeds[-1]}), in process\n")
    print(
        "| case | estimator | bound | position: efficiency (last RMSE / √bound [m]) | velocity: efficiency (last "
        "RMSE / √bound [m/s]) |\n|---|---|---|---|---|"
    )
    with ProcessPoolExecutor(args.jobs) as pool:
        for case, cfg in cases:
            runs = list(pool.map(_run, [(cfg, estimators, s) for s in seeds]))
            scored, series = score_bags(runs, with_series=True)
            print("\n".join(table_rows(case, scored["estimators"])), flush=True)
            if args.out:
                write_report(args.out / case, {scored["scenario"]: scored["estimators"]}, {scored["scenario"]: series})
    return 0


if __name__ == "__main__":
    sys.exit(main())
