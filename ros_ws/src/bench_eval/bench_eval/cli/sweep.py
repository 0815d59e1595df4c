"""Parameter sweep: every cell of a grid of the scenario's ``sweeps`` section through the ROS 2 graph, N seeded
runs per cell, every bag kept, and a paper-style report (grid schema: ``bench_eval.sweep``).

Run i of every cell uses seed SEED0 + i and writes OUT/CELL/run_NNN/bag; up to --jobs runs go in parallel, each
on its own ROS_DOMAIN_ID, all nodes of a run in one process. Outputs: OUT/sweep.json (cells, scores with
per-run values, the study's extra rows) and OUT/table.md with its PNG plots.

With --scheduler the runs go to a Dask distributed cluster instead (each worker runs whole runs on its own
host, DDS on that host, bags written to OUT on a file system every worker shares at the same path; a run whose
worker is lost is run again elsewhere). --resume keeps the complete runs already in OUT and runs the others.

Examples:
  .venv/bin/python scripts/sweep.py formation_cqkf --grid tables --runs 12 --jobs 2 --out runs/sweep-tables
  .venv/bin/python scripts/sweep.py formation_cqkf --grid tables --runs 40 --scheduler tcp://head:8786 --out /shared/t
  .venv/bin/python scripts/sweep.py formation_cqkf --grid interval --runs 4 --out runs/sweep-interval
  .venv/bin/python scripts/sweep.py formation_cqkf --grid noise --runs 2 --set time.duration=600
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"

from bench_engine.cli.batch_options import add_batch_arguments, check_batch_arguments  # noqa: E402
from bench_engine.cli.guard import (  # noqa: E402
    ArgumentParser,
    check_output,
    check_writable,
    exit_codes,
    is_file_error,
    run_main,
    writing,
)
from bench_engine.cli.options import add_estimators_option, names  # noqa: E402
from bench_engine.config import ScenarioError  # noqa: E402
from bench_engine.process import exit_now  # noqa: E402
from bench_eval.sweep import SweepRun, load_grid, reusable, validate, write_outputs  # noqa: E402

EPILOG = exit_codes(
    c0="every run completed and every cell was scored; sweep.json and table.md written",
    c1="a run or a cell's scoring failed (each named; the other cells are reported), or the Dask scheduler could "
    "not be reached",
    c2="bad input, stopped before any run started: an unknown or invalid scenario (a YAML syntax error names the "
    "file and line), grid, cell value or --set key or value, runs already in OUT (without --resume), or an "
    "output directory that cannot be written (a file, read-only, no space left)",
)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = ArgumentParser(description=__doc__, epilog=EPILOG)
    p.add_argument("scenario", help="scenario name or YAML path (with a 'sweeps' section)")
    p.add_argument("--grid", required=True, help="name of the grid in the scenario's 'sweeps' section")
    p.add_argument("--runs", type=int, default=1, help="Monte Carlo runs per cell (default 1)")
    p.add_argument("--out", type=Path, default=None, help="output directory (default runs/sweep-SCENARIO-GRID)")
    p.add_argument("--seed0", type=int, default=1, help="seed of run 0 of every cell (run i uses seed0 + i)")
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="scenario override applied to every cell after its own, repeatable",
    )
    add_estimators_option(p, default_text="each cell's 'estimators'")
    add_batch_arguments(p)
    p.add_argument("--json", action="store_true", help="print sweep.json instead of the summary")
    args = p.parse_args(argv)
    if names(args.estimators):  # every cell's selection: the scenario key, set after the cells' own
        args.overrides.append(f"estimators=[{', '.join(names(args.estimators))}]")
    check_batch_arguments(p, args)
    return args


def invoked_as() -> str:
    """The program recorded in sweep.json: scripts/sweep.py when run from the repository, else bench_sweep."""
    return "scripts/sweep.py" if Path(sys.argv[0]).name == "sweep.py" else "bench_sweep"


def main(argv: list[str] | None = None) -> int:
    """Run the grid of the command line; the exit codes of EPILOG."""
    args = parse_args(argv)
    args.out = args.out or Path(f"runs/sweep-{Path(args.scenario).stem}-{args.grid}")
    check_output(args.out)  # a file in the way, or an existing OUT that takes no file: before the validation
    try:
        grid = load_grid(args.scenario, args.grid, args.overrides)
        validate(grid, args.seed0)
        done = reusable(args.out, grid, args.runs, args.seed0, args.resume)
    except ScenarioError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    check_writable(args.out)  # a file, read-only or full: one line (run_main), before any run starts
    print(
        f"[sweep] {grid.scenario}/{grid.name}: {len(grid.cells)} cells x {args.runs} runs "
        f"({len(done)} reused), {args.jobs} jobs, out {args.out}",
        file=sys.stderr,
    )
    started = time.monotonic()
    sweep_run = SweepRun(grid, args.out, args.runs, args.seed0, done)
    domains = list(range(args.domain_base, args.domain_base + args.jobs)) if args.domain_base is not None else None
    try:
        with writing(args.out):
            sweep_run.run(args.jobs, domains, args.scheduler, args.retries)
    except OSError as err:
        if is_file_error(err):
            raise  # an output that cannot be written: run_main tells it (exit code 2)
        print(f"error: {' '.join(str(err).split())}", file=sys.stderr)  # e.g. no Dask scheduler at that address
        return 1
    wall = time.monotonic() - started
    command = " ".join([invoked_as()] + (sys.argv[1:] if argv is None else argv))
    with writing(args.out):
        sweep = write_outputs(
            sweep_run,
            {
                "runs_per_cell": args.runs,
                "seed0": args.seed0,
                "jobs": args.jobs,
                "wall_s": round(wall, 1),
                "runs_reused": len(done),
                "command": command,
            },
        )
    print(json.dumps(sweep, indent=1) if args.json else (args.out / "table.md").read_text())
    print(f"[sweep] {len(sweep_run.specs)} runs in {wall:.0f} s; table {args.out / 'table.md'}", file=sys.stderr)
    for r in sweep_run.reruns:
        print(f"[sweep] ran again: {r}", file=sys.stderr)
    for f in sweep_run.failures:
        print(f"[sweep] failed: {f}", file=sys.stderr)
    return 1 if sweep_run.failures else 0


def command() -> None:
    """Console script ``bench_sweep``: ``main`` on the command line (its failures told in one line:
    bench_engine.cli.guard), then exit without the interpreter's teardown (bench_engine.process.exit_now)."""
    exit_now(run_main(main))
