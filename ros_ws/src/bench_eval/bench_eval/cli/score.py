"""Score recorded runs offline, from their bags only.

Several bags of the same scenario are Monte Carlo runs: RMSE is taken per time step over the runs
(paper 000 eq. 35). Prints a summary table, or JSON with --json; --plots DIR writes report.md and PNGs.
A bag a killed recorder left incomplete is recovered first (bench_engine.recovery).

The bags are read, and their offline estimators and bounds computed, --jobs at a time (default: every CPU),
or on a Dask cluster with --scheduler. Each offline estimator's result (e.g. grace_velocity's orbit fits) is
kept in the bag's directory (offline_cache/) and read back when the same estimator, with the same parameters
and code, scores the same bag again (bench_eval.offline_cache); --no-cache neither reads nor writes it.

Examples:
  .venv/bin/python scripts/score.py runs/demo/leo_radar/bag
  .venv/bin/python scripts/score.py runs/mc/run_*/bag --json --plots runs/mc/report
  .venv/bin/python scripts/score.py runs/mc/run_*/bag --jobs 1 --no-cache
  .venv/bin/python scripts/score.py /shared/mc/run_*/bag --scheduler tcp://head:8786
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads: one BLAS thread per worker (--jobs)

from bench_engine.cli.guard import ArgumentParser, check_output, exit_codes, run_main, writing  # noqa: E402
from bench_eval.scoring import NothingToScore, score_bags  # noqa: E402
from bench_eval.summary import print_summary  # noqa: E402

EPILOG = exit_codes(
    c0="the bags were scored",
    c2="bad input: a directory that is not a bag, an unrecoverable or "
    "damaged bag, bags of different scenarios, a bag whose scenario needs a component not "
    "registered here, a bag with nothing to score, or a --plots directory that cannot be written",
)


def main(argv: list[str] | None = None) -> int:
    """Score the bags of the command line; the exit code of the module docstring."""
    p = ArgumentParser(description=__doc__, epilog=EPILOG)
    p.add_argument("bags", nargs="+", type=Path, help="bag directories (metadata.yaml + .mcap) of one scenario")
    p.add_argument("--json", action="store_true", help="print the scores as JSON")
    p.add_argument("--plots", type=Path, metavar="DIR", help="write report.md and plots into DIR")
    p.add_argument(
        "--jobs",
        type=int,
        default=None,
        help="bags prepared in parallel (read, offline estimators, bounds; default: every CPU)",
    )
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="prepare the bags on a Dask distributed cluster: the scheduler's address "
        "(tcp://HOST:8786), or 'local' for a local cluster of --jobs worker processes",
    )
    p.add_argument(
        "--no-cache",
        action="store_true",
        help="run every offline estimator again, without reading or writing the cache beside the bag",
    )
    args = p.parse_args(argv)
    if args.jobs is not None and args.jobs < 1:
        p.error("--jobs must be >= 1")
    missing = [str(b) for b in args.bags if not (b / "metadata.yaml").is_file() and not list(b.glob("*.mcap"))]
    if missing:
        print(f"error: not a bag directory (no metadata.yaml or .mcap file): {', '.join(missing)}", file=sys.stderr)
        return 2
    if args.plots:
        check_output(args.plots)  # a file in the way, read-only, full: said before the bags are read
    try:
        options = {"jobs": args.jobs, "scheduler": args.scheduler, "cache": not args.no_cache}
        scored, series = (
            score_bags(args.bags, with_series=True, **options)
            if args.plots
            else (score_bags(args.bags, **options), None)
        )
    except NothingToScore as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(json.dumps(scored, indent=1) if args.json else print_summary(scored))
    if args.plots:
        from bench_eval.report import write_report  # matplotlib: most of a summary's start-up, only for plots

        with writing(args.plots):
            path = write_report(
                args.plots, {scored["scenario"]: scored["estimators"]}, {scored["scenario"]: series} if series else {}
            )
        print(f"report: {path}", file=sys.stderr)
    return 0


def command() -> None:
    """Console script ``bench_score``: ``main`` with its failures told in one line (bench_engine.cli.guard)."""
    sys.exit(run_main(main))
