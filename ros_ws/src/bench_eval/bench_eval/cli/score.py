"""Score recorded runs offline, from their bags only.

Several bags of the same scenario are Monte Carlo runs: RMSE is taken per time step over the runs
(paper 000 eq. 35). Prints a summary table, or JSON with --json; --plots DIR writes report.md and PNGs.
A bag a killed recorder left incomplete is recovered first (bench_engine.recovery).
Exit code: 0 on success, 2 for a directory that is not a bag, an unrecoverable bag or one with nothing to score.

Examples:
  .venv/bin/python scripts/score.py runs/demo/leo_radar/bag
  .venv/bin/python scripts/score.py runs/mc/run_*/bag --json --plots runs/mc/report
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    """Score the bags of the command line; the exit code of the module docstring."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("bags", nargs="+", type=Path, help="bag directories (metadata.yaml + .mcap) of one scenario")
    p.add_argument("--json", action="store_true", help="print the scores as JSON")
    p.add_argument("--plots", type=Path, metavar="DIR", help="write report.md and plots into DIR")
    args = p.parse_args(argv)
    missing = [str(b) for b in args.bags if not (b / "metadata.yaml").is_file() and not list(b.glob("*.mcap"))]
    if missing:
        print(f"error: not a bag directory (no metadata.yaml or .mcap file): {', '.join(missing)}", file=sys.stderr)
        return 2
    from bench_engine.bag import BagDamaged
    from bench_engine.config import ScenarioError
    from bench_engine.recovery import BagUnrecoverable
    from bench_eval.report import write_report
    from bench_eval.scoring import NothingToScore, print_summary, score_bags
    try:
        scored, series = score_bags(args.bags, with_series=True)
    except (NothingToScore, BagDamaged, BagUnrecoverable, ScenarioError, FileNotFoundError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(json.dumps(scored, indent=1) if args.json else print_summary(scored))
    if args.plots:
        path = write_report(args.plots, {scored["scenario"]: scored["filters"]},
                            {scored["scenario"]: series} if series else {})
        print(f"report: {path}", file=sys.stderr)
    return 0


def command() -> None:
    """Console script ``bench_score``."""
    sys.exit(main())
