"""Monte Carlo: N seeded runs of a scenario through the ROS 2 graph, every bag kept, metrics over runs.

Run i uses seed SEED0 + i and writes OUT/run_NNN/bag. Up to --jobs runs execute in parallel, each on its
own ROS_DOMAIN_ID (DDS stays on this host). By default each run's nodes share one process (real DDS, one
executor); --multiprocess starts one process per node instead. Metrics are aggregated across runs as in
paper 000 eq. 35 (RMSE per time step over the N runs) and written to OUT/score.json and OUT/report/; the bags
are scored --jobs at a time (or on the --scheduler's cluster), each offline estimator's result kept beside its
bag for the next scoring (scripts/score.py).

With --scheduler the runs go to a Dask distributed cluster instead: each worker runs whole runs on its own
host (DDS on that host, a free ROS domain there) and writes the bags to OUT, which must be on a file system
every worker shares at the same path; a run whose worker is lost is run again elsewhere. With either, a run
one of whose nodes is killed (by the OOM killer, an operator) is set aside as OUT/run_NNN.killedK and run
again, twice at most, with a line naming the run and the node. --resume keeps the complete runs already in OUT
(same configuration and seed) and makes only the others.

Examples:
  .venv/bin/python scripts/montecarlo.py leo_radar --runs 100 --jobs 2 --out runs/mc
  .venv/bin/python scripts/montecarlo.py leo_radar --runs 10 --estimators ukf --set time.duration=120
  .venv/bin/python scripts/montecarlo.py leo_radar --runs 400 --scheduler tcp://head:8786 --out /shared/mc
  .venv/bin/python scripts/montecarlo.py leo_radar --runs 400 --scheduler tcp://head:8786 --out /shared/mc --resume
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads: one BLAS thread per scoring worker

from bench_engine import phases  # noqa: E402
from bench_engine.cli.batch_options import add_batch_arguments, check_batch_arguments  # noqa: E402
from bench_engine.cli.guard import ArgumentParser, check_writable, exit_codes, is_file_error, run_main, writing  # noqa: E402
from bench_engine.cli.options import add_estimators_option  # noqa: E402
from bench_engine.config import ScenarioError  # noqa: E402
from bench_engine.process import exit_now  # noqa: E402
from bench_eval.errors import NothingToScore  # noqa: E402
from bench_eval.montecarlo import MonteCarlo, run_montecarlo  # noqa: E402
from bench_eval.summary import print_summary  # noqa: E402

EPILOG = exit_codes(
    c0="every run completed; scores and report written",
    c1="a run failed (each failed run is named with its log; the others are scored), none could be scored, or "
    "the Dask scheduler could not be reached",
    c2="bad input, stopped before any run started: an unknown or invalid scenario (a YAML syntax error names the "
    "file and line), estimator, variant or --set key or value, run directories already in OUT (without "
    "--resume), or an output directory that cannot be written (a file, read-only, no space left)",
)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = ArgumentParser(description=__doc__, epilog=EPILOG)
    p.add_argument("scenario", help="scenario name or YAML path")
    p.add_argument("--runs", type=int, required=True, help="number of Monte Carlo runs")
    add_estimators_option(p)
    p.add_argument("--out", type=Path, default=None, help="output directory (default runs/mc-SCENARIO)")
    p.add_argument("--seed0", type=int, default=1, help="seed of run 0 (run i uses seed0 + i)")
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="scenario override, repeatable",
    )
    p.add_argument("--variant", help="the scenario's named variants (comma-separated, in order)")
    p.add_argument("--multiprocess", action="store_true", help="one process per node in every run")
    add_batch_arguments(p)
    p.add_argument("--json", action="store_true", help="print the aggregated scores as JSON")
    args = p.parse_args(argv)
    check_batch_arguments(p, args)
    return args


def main(argv: list[str] | None = None) -> int:
    """Run the Monte Carlo of the command line; the exit codes of EPILOG."""
    args = parse_args(argv)
    mc = MonteCarlo(
        args.scenario,
        args.out or Path(f"runs/mc-{Path(args.scenario).stem}"),
        args.runs,
        args.seed0,
        args.estimators,
        args.variant,
        args.overrides,
        args.multiprocess,
    )
    phases.mark_process_start("montecarlo", mc.out.resolve())
    domains = list(range(args.domain_base, args.domain_base + args.jobs)) if args.domain_base is not None else None
    check_writable(mc.out)  # a file, read-only or full: one line (run_main), before anything starts
    try:
        with writing(mc.out):
            scored, failures = run_montecarlo(mc, args.jobs, domains, args.scheduler, args.resume, args.retries)
    except ScenarioError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except (RuntimeError, OSError) as err:
        if is_file_error(err):
            raise  # an output that cannot be written: run_main tells it (exit code 2)
        print(f"error: {' '.join(str(err).split())}", file=sys.stderr)  # e.g. no Dask scheduler there
        return 1
    print(json.dumps(scored, indent=1) if args.json else print_summary(scored))
    print(f"[montecarlo] report: {mc.out / 'report' / 'report.md'}", file=sys.stderr)
    for f in failures:
        print(f"[montecarlo] failed: {f}", file=sys.stderr)
    return 1 if failures else 0


def command() -> None:
    """Console script ``bench_montecarlo``: ``main`` on the command line (its failures told in one line:
    bench_engine.cli.guard), then exit without the interpreter's teardown (bench_engine.process.exit_now)."""
    exit_now(run_main(main, expected={NothingToScore: 1}))
