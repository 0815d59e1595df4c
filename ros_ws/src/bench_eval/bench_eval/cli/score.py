"""Score recorded runs offline, from their bags only.

Several bags of the same scenario are Monte Carlo runs: RMSE is taken per time step over the runs
(paper 000 eq. 35). Prints a summary table, or JSON with --json; --plots DIR writes report.md and PNGs.
A bag a killed recorder left incomplete is recovered first (bench_engine.recovery).

Examples:
  .venv/bin/python scripts/score.py runs/demo/leo_radar/bag
  .venv/bin/python scripts/score.py runs/mc/run_*/bag --json --plots runs/mc/report
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from bench_engine.cli.guard import ArgumentParser, check_output, exit_codes, run_main, writing
from bench_eval.scoring import NothingToScore, print_summary, score_bags

EPILOG = exit_codes(c0="the bags were scored", c2="bad input: a directory that is not a bag, an unrecoverable or "
                    "damaged bag, bags of different scenarios, a bag whose scenario needs a component not "
                    "registered here, a bag with nothing to score, or a --plots directory that cannot be written")


def main(argv: list[str] | None = None) -> int:
    """Score the bags of the command line; the exit code of the module docstring."""
    p = ArgumentParser(description=__doc__, epilog=EPILOG)
    p.add_argument("bags", nargs="+", type=Path, help="bag directories (metadata.yaml + .mcap) of one scenario")
    p.add_argument("--json", action="store_true", help="print the scores as JSON")
    p.add_argument("--plots", type=Path, metavar="DIR", help="write report.md and plots into DIR")
    args = p.parse_args(argv)
    missing = [str(b) for b in args.bags if not (b / "metadata.yaml").is_file() and not list(b.glob("*.mcap"))]
    if missing:
        print(f"error: not a bag directory (no metadata.yaml or .mcap file): {', '.join(missing)}", file=sys.stderr)
        return 2
    if args.plots:
        check_output(args.plots)  # a file in the way, read-only, full: said before the bags are read
    try:
        scored, series = score_bags(args.bags, with_series=True) if args.plots else (score_bags(args.bags), None)
    except NothingToScore as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(json.dumps(scored, indent=1) if args.json else print_summary(scored))
    if args.plots:
        from bench_eval.report import write_report  # matplotlib: most of a summary's start-up, only for plots
        with writing(args.plots):
            path = write_report(args.plots, {scored["scenario"]: scored["estimators"]},
                                {scored["scenario"]: series} if series else {})
        print(f"report: {path}", file=sys.stderr)
    return 0


def command() -> None:
    """Console script ``bench_score``: ``main`` with its failures told in one line (bench_engine.cli.guard)."""
    sys.exit(run_main(main))
