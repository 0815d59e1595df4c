"""One run of a scenario through the ROS 2 graph, recording its bag: ``python -m bench_engine.run SCENARIO``.

The argument parser is shared with scripts/launch.py (which adds scoring). DDS stays on this host
(ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST) and the run takes a ROS domain no other bench run holds.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # one BLAS thread per process: see launcher.local_dds_env

from bench_engine import phases  # noqa: E402
from bench_engine.cli.guard import ArgumentParser, check_output, exit_codes, run_main, writing  # noqa: E402
from bench_engine.cli.options import add_estimators_option, names  # noqa: E402
from bench_engine.config import ScenarioError, available_scenarios  # noqa: E402
from bench_engine.launcher import RunPlan, prepare_run, run_graph  # noqa: E402
from bench_engine.process import exit_now  # noqa: E402
from bench_engine.timegrid import build_time  # noqa: E402

RUN_EXIT_CODES = {
    "c0": "the run completed (the bag is closed and complete)",
    "c1": "a node failed (named, with the tail of its log; the bag is closed, or recovered)",
    "c2": "bad input, stopped before any node started: an unknown or invalid scenario (a YAML syntax error "
    "names the file and line), estimator, variant, --set key or value, a ROS domain held by another run, or "
    "an output directory that cannot be written (a file, read-only, no space left)",
    "c124": "the run did not end within its time limit (the nodes were stopped)",
}
"""Exit codes of one run (``--help``); 128+N on signal N leaves the bag closed and complete."""


def add_run_arguments(p: argparse.ArgumentParser) -> None:
    """The options of one run (scenario, estimators, seed, output, overrides, variants, process mode)."""
    p.add_argument("scenario", help=f"scenario name ({', '.join(available_scenarios())}) or a YAML path")
    add_estimators_option(p)
    p.add_argument("--seed", type=int, help="random seed of the sensors (default: the scenario's seed)")
    p.add_argument("--out", default=None, help="output directory (default: runs/SCENARIO-TIMESTAMP)")
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scenario key, e.g. --set sensors.radar.sigma_range=10 (repeatable)",
    )
    p.add_argument("--variant", help="apply the scenario's named variants (comma-separated, in order)")
    p.add_argument(
        "--single-process", action="store_true", help="run every node in this one process, pinned to one CPU"
    )
    p.add_argument(
        "--no-pin", action="store_true", help="with --single-process: let the process's threads use every CPU"
    )
    p.add_argument(
        "--domain-id",
        type=int,
        default=None,
        help="ROS_DOMAIN_ID of this run (default: the first one no other bench run holds)",
    )
    p.add_argument(
        "--fresh-nodes",
        action="store_true",
        help="start each node process as a fresh interpreter (slower start-up) instead of forking it "
        "from the launcher, which has imported the nodes and built the truth already",
    )
    p.add_argument(
        "--executor",
        choices=["events", "single"],
        default="events",
        help="rclpy executor (events = rclpy.experimental.EventsExecutor)",
    )


def launch(args: argparse.Namespace) -> tuple[int, RunPlan | None]:
    """Validate, run and time the graph of ``args``; returns (exit code, plan)."""
    out = Path(args.out or f"runs/{Path(args.scenario).stem}-{time.strftime('%Y%m%d-%H%M%S')}")
    phases.mark_process_start("launcher", out.resolve())
    try:
        with writing(out):  # a file error (a file in the way, read-only, no space) is told in one line
            check_output(out)  # before the validation, which may take seconds
            plan = prepare_run(
                args.scenario,
                out,
                names(args.estimators),
                args.seed,
                args.overrides,
                args.variant,
                extra={"executor": args.executor},
            )
    except ScenarioError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2, None
    phases.mark("validated", "launcher", plan.out)
    started = time.monotonic()
    code = run_graph(
        plan, args.domain_id, args.single_process, args.executor, pin=not args.no_pin, fork_nodes=not args.fresh_nodes
    )
    wall = time.monotonic() - started
    phases.mark("run_end", "launcher", plan.out)
    timing = plan.out / "timing.json"
    if timing.exists():
        t = json.loads(timing.read_text())
        sim = (t["steps"] - 1) * build_time(plan.run["scenario"]).dt
        print(
            f"[launch] wall {wall:.1f} s (start-up {t['startup_s']:.1f} s, stepping {t['stepping_s']:.1f} s: "
            f"{sim / max(t['stepping_s'], 1e-9):.0f}x real time); bag {plan.bag_dir}",
            file=sys.stderr,
        )
    return code, plan


def main(argv: list[str] | None = None) -> int:
    """One run of the command line; the exit codes of RUN_EXIT_CODES, every failure told in one line but a bug's
    (bench_engine.cli.guard)."""

    def run(args: list[str] | None) -> int:
        p = ArgumentParser(description=__doc__, epilog=exit_codes(**RUN_EXIT_CODES))
        add_run_arguments(p)
        return launch(p.parse_args(args))[0]

    return run_main(run, argv)


if __name__ == "__main__":
    exit_now(main())
