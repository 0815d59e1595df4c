"""Run a scenario through the ROS 2 graph, record a rosbag2-style MCAP bag, and print its score.

Examples:
  .venv/bin/python scripts/launch.py leo_radar
  .venv/bin/python scripts/launch.py leo_radar --estimators ukf --seed 7 --out runs/ukf7
  .venv/bin/python scripts/launch.py leo_radar --set sensors.radar.p_detect=1.0 --single-process
  .venv/bin/python scripts/launch.py leo_radar --variant table3_angles

DDS stays on this host (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST); each run uses its own ROS_DOMAIN_ID.
"""

from __future__ import annotations

from bench_engine import phases
from bench_engine.cli.guard import ArgumentParser, exit_codes, run_main
from bench_engine.process import exit_now
from bench_engine.run import RUN_EXIT_CODES, add_run_arguments, launch
from bench_eval.scoring import NothingToScore
from bench_eval.summary import score_run

EPILOG = exit_codes(**{**RUN_EXIT_CODES, "c1": RUN_EXIT_CODES["c1"] + ", or the estimators published nothing to score"})


def main(argv: list[str] | None = None) -> int:
    """Run, then score the bag unless --no-score; the exit codes of EPILOG."""
    p = ArgumentParser(description=__doc__, epilog=EPILOG)
    add_run_arguments(p)
    p.add_argument("--no-score", action="store_true", help="do not score the bag after the run")
    p.add_argument("--json", action="store_true", help="print the score as JSON")
    args = p.parse_args(argv)
    code, plan = launch(args)
    if code != 0 or args.no_score:
        return code
    print(score_run(plan.out, args.json))  # NothingToScore: exit code 1 (command)
    phases.mark("scored", "launcher", plan.out)
    return 0


def command() -> None:
    """Console script ``bench_launch``: ``main`` on the command line (its failures told in one line:
    bench_engine.cli.guard), then exit without the interpreter's teardown (bench_engine.process.exit_now)."""
    exit_now(run_main(main, expected={NothingToScore: 1}))
