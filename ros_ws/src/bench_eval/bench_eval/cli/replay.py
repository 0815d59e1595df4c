"""Re-run estimators on the measurements of a recorded bag, and record (and score) a new bag.

A player node re-publishes the recorded truth and measurements unchanged (same stamps, same noise), paced by
the new estimators, so any estimator can be compared on identical data. The scenario comes from the bag's
run_config.yaml; --set changes it (e.g. a filter's parameters) for the replay.

Examples:
  .venv/bin/python scripts/replay.py runs/demo/leo_radar/bag --estimators ukf --out runs/replay-ukf
  .venv/bin/python scripts/replay.py runs/demo/leo_radar/bag --estimators ukf --set filters.ukf.params.alpha=0.5
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import yaml

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads: see bench_engine.launcher

from bench_engine import yamlio  # noqa: E402
from bench_engine.bag_errors import BagDamaged  # noqa: E402
from bench_engine.bag_reader import BagReader  # noqa: E402
from bench_engine.cli.guard import ArgumentParser, check_output, exit_codes, run_main, writing  # noqa: E402
from bench_engine.cli.options import add_estimators_option, names  # noqa: E402
from bench_engine.config import ScenarioError, apply_overrides  # noqa: E402
from bench_engine.launcher import prepare_run, run_graph  # noqa: E402
from bench_engine.process import exit_now  # noqa: E402
from bench_eval.scoring import NothingToScore  # noqa: E402
from bench_eval.summary import score_run  # noqa: E402

EPILOG = exit_codes(
    c0="the replay completed and its bag was scored",
    c1="a node failed (named, with the tail of its log), or the new estimators published nothing to score",
    c2="bad input, stopped before any node started: a directory that is not a bag recorded by this bench, a "
    "damaged bag, an invalid estimator or --set key or value, a ROS domain held by another run, or an output "
    "directory that cannot be written (a file, read-only, no space left)",
    c124="the replay did not end within its time limit",
)


def recorded_run(bag: Path) -> dict:
    """The bag's run_config.yaml (its resolved scenario), after checking that the bag can be read at all."""
    config = bag / "run_config.yaml"
    if not config.is_file():
        raise ScenarioError(f"{bag} is not a bag recorded by this bench (no run_config.yaml)")
    BagReader(bag).topics()  # no .mcap, a damaged metadata.yaml or file: BagDamaged, before anything starts
    try:
        recorded = yamlio.load(config.read_text())
        recorded["scenario"]["scenario"]
    except (yaml.YAMLError, UnicodeDecodeError, LookupError, TypeError) as err:
        raise BagDamaged(f"{config} is not a run config written by this bench (damaged or edited)") from err
    return recorded


def main(argv: list[str] | None = None) -> int:
    """Replay the bag of the command line into fresh estimators; the exit codes of EPILOG."""
    p = ArgumentParser(description=__doc__, epilog=EPILOG)
    p.add_argument("bag", type=Path, help="bag directory recorded by launch.py / montecarlo.py")
    add_estimators_option(p, required=True)
    p.add_argument("--out", type=Path, default=None, help="output directory (default runs/replay-TIMESTAMP)")
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="scenario override for the replay (estimators only: the data are fixed), repeatable",
    )
    p.add_argument("--single-process", action="store_true", help="run every node in this one process")
    p.add_argument(
        "--domain-id", type=int, default=None, help="ROS_DOMAIN_ID (default: the first one no other bench run holds)"
    )
    p.add_argument("--json", action="store_true", help="print the score as JSON")
    args = p.parse_args(argv)
    out = args.out or Path(f"runs/replay-{time.strftime('%Y%m%d-%H%M%S')}")
    try:
        recorded = recorded_run(args.bag)
        cfg = apply_overrides(recorded["scenario"], args.overrides)
        with writing(out):
            check_output(out)  # before the validation
            plan = prepare_run(
                cfg["scenario"],
                out,
                names(args.estimators),
                recorded.get("seed"),
                source="player",
                extra={"replay_bag": str(args.bag.resolve())},
                cfg=cfg,
            )
    except (ScenarioError, BagDamaged) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(f"[replay] {args.bag} -> {plan.bag_dir} with {plan.run['estimators']}", file=sys.stderr)
    code = run_graph(plan, args.domain_id, args.single_process, tag="replay")
    if code != 0:
        return code
    print(score_run(plan.out, args.json))  # NothingToScore: exit code 1 (command)
    return 0


def command() -> None:
    """Console script ``bench_replay``: ``main`` with its failures told in one line (bench_engine.cli.guard), then
    exit without the interpreter's teardown (bench_engine.process.exit_now; a --single-process replay leaves its
    ROS objects to it: bench_engine.launcher.run_single_process)."""
    exit_now(run_main(main, expected={NothingToScore: 1}))
