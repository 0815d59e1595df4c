"""The options of the commands that run batches (scripts/montecarlo.py, scripts/sweep.py): how many runs at a
time, on which ROS domains or on a Dask cluster, how often a failed task is retried, whether complete runs are
kept (bench_engine.batch)."""

from __future__ import annotations

import argparse

MAX_DOMAIN_ID = 101
"""The largest ROS_DOMAIN_ID a batch uses (the portable range of ROS 2 domain ids)."""


def add_batch_arguments(p: argparse.ArgumentParser) -> None:
    """--jobs, --domain-base, --scheduler, --retries and --resume."""
    p.add_argument("--jobs", type=int, default=2, help="runs in parallel (default 2)")
    p.add_argument(
        "--domain-base",
        type=int,
        default=None,
        help="job j uses ROS_DOMAIN_ID domain-base + j (default: each run reserves a free domain)",
    )
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run on a Dask distributed cluster: the scheduler's address (tcp://HOST:8786), or "
        "'local' for a local cluster of --jobs worker processes",
    )
    p.add_argument(
        "--retries", type=int, default=2, help="with --scheduler: attempts more for a run whose task fails (default 2)"
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="keep the complete runs already in OUT (same configuration and seed), run the others",
    )


def check_batch_arguments(p: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """A usage error (p.error) for --runs or --jobs below 1, --domain-base with --scheduler or out of range,
    negative --retries."""
    if args.runs < 1 or args.jobs < 1:
        p.error("--runs and --jobs must be >= 1")
    if args.scheduler is not None and args.domain_base is not None:
        p.error("--domain-base is for local runs: with --scheduler each run takes a free domain on its worker's host")
    if args.retries < 0:
        p.error("--retries must be >= 0")
    if args.domain_base is not None and (args.domain_base < 0 or args.domain_base + args.jobs - 1 > MAX_DOMAIN_ID):
        p.error(f"--domain-base + --jobs - 1 must be in [0, {MAX_DOMAIN_ID}] (ROS_DOMAIN_ID range)")
