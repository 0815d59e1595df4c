"""The main job (`make demo`): run every registered study through the ROS 2 graph, score the bags, write a report.

For each study (its scenario and default filters, side by side) the graph runs, the recorder writes a
rosbag2-style MCAP bag, the scorer reads it back, and OUT/report.md opens with the papers' claims and the bench's
verdicts, then a section per study (bench next to the paper) with plots. Each study runs as many seeds as it asks
for (its Study's ``demo_runs``: enough for its claims to be decided where its runs are cheap); a claim the runs
do not decide says "undecided" with the runs it would need (bench_eval.claims). --runs N runs N seeds of every
study instead. A study's single run has one process per node; more are a Monte Carlo (each run's nodes in one
process). The runs of every study form one batch, two at a time, the longest simulated run first.

Example:
  .venv/bin/python scripts/demo.py --out runs/demo
  .venv/bin/python scripts/demo.py --out runs/demo --runs 20
"""

from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads

from bench_engine import plugins  # noqa: E402
from bench_engine.batch import RunSpec, run_batch  # noqa: E402
from bench_engine.cli.guard import ArgumentParser, check_writable, exit_codes, run_main, writing  # noqa: E402
from bench_engine.config import load_scenario  # noqa: E402
from bench_eval.errors import NothingToScore  # noqa: E402
from bench_eval.report import write_report  # noqa: E402
from bench_eval.scoring import score_bags  # noqa: E402
from bench_eval.study import study  # noqa: E402
from bench_eval.summary import print_summary  # noqa: E402

EPILOG = exit_codes(
    c0="every study ran and was scored; the report is written",
    c1="a study's run failed (its logs named), or its filters published nothing to score",
    c2="bad input, stopped before any run started: an unknown study, --runs < 1, or an output directory that "
    "cannot be written (a file, read-only, no space left)",
)


def run_studies(names: list[str], out: Path, runs: int | None) -> dict[str, list[Path]]:
    """Run every chosen study's seeds 1..n (n = ``runs``, else its ``demo_runs``; a single run with a process per
    node, more with each run's nodes in one process) in one batch, two at a time, the longest simulated run
    first: a study's single long run then overlaps the other studies' short ones instead of running alone. Returns each
    study's bag directories."""
    specs: dict[str, list[RunSpec]] = {}
    for name in names:
        n = runs or study(name).demo_runs
        shutil.rmtree(out / name, ignore_errors=True)
        specs[name] = [RunSpec(name, out / name / f"run_{i:03d}", i + 1, multiprocess=n == 1) for i in range(n)]
    longest_first = sorted(names, key=lambda name: -float(load_scenario(name)["time"]["duration"]))
    results = run_batch([spec for name in longest_first for spec in specs[name]], jobs=2, desc="demo runs")
    failed = [r for r in results if not r.ok]
    if failed:
        raise RuntimeError(f"{len(failed)} run(s) failed; logs: {', '.join(str(r.spec.log) for r in failed)}")
    return {name: [spec.bag for spec in specs[name]] for name in names}


def main(argv: list[str] | None = None) -> int:
    """Run, score and report the chosen studies; the exit codes of EPILOG."""
    studies = plugins.names("studies")
    p = ArgumentParser(description=__doc__, epilog=EPILOG)
    p.add_argument("--out", type=Path, default=Path("runs/demo"), help="output directory (default runs/demo)")
    p.add_argument(
        "--runs",
        type=int,
        default=None,
        help="Monte Carlo runs of every study (default: each study's own count, its demo_runs)",
    )
    p.add_argument("--studies", default=",".join(studies), help=f"comma-separated subset of {studies}")
    args = p.parse_args(argv)
    chosen = [s for s in args.studies.split(",") if s]
    unknown = sorted(set(chosen) - set(studies))
    if unknown or (args.runs is not None and args.runs < 1):
        p.error(f"unknown study {unknown}; registered: {studies}" if unknown else "--runs must be >= 1")
    check_writable(args.out)  # a file, read-only or full: one line (run_main), before any run starts
    try:
        with writing(args.out):
            bags = run_studies(chosen, args.out, args.runs)
    except RuntimeError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    scored_all, series_all = {}, {}
    for name in chosen:
        scored, series = score_bags(bags[name], with_series=True)
        with writing(args.out / name):
            (args.out / name / "score.json").write_text(json.dumps(scored, indent=1))
        print(print_summary(scored))
        scored_all[name] = scored["estimators"]
        if series:
            series_all[name] = series
    with writing(args.out):
        report = write_report(args.out, scored_all, series_all)
    print(f"[demo] report: {report}", file=sys.stderr)
    return 0


def command() -> None:
    """Console script ``bench_demo``: ``main`` with its failures told in one line (bench_engine.cli.guard)."""
    sys.exit(run_main(main, expected={NothingToScore: 1}))
