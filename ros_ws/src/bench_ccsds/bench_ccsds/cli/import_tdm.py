"""Replay a CCSDS Tracking Data Message into the bench's estimators, like a bag: the TDM's measurements (and an
optional OEM as the reference trajectory) become OUT/input/bag (bench_ccsds/ingest.py: the scenario gives the
station, the noise R and the time line), a player publishes them on the sensor's topic with their stamps, the
estimators run in the graph and OUT/bag is scored. Without a reference the score is what needs no truth (NIS
consistency, post-fit residuals, the estimators' own convergence: bench_eval/consistency.py); with one, also the
errors against it.

Examples:
  .venv/bin/python scripts/import_tdm.py runs/iss/ccsds/radar.tdm --scenario leo_radar --variant iss --out runs/tdm
  .venv/bin/python scripts/import_tdm.py radar.tdm --scenario leo_radar --variant iss --reference truth.oem \\
      --estimators ekf,ukf --out runs/tdm-ref
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads: see bench_engine.launcher

from bench_ccsds.ingest import import_tdm  # noqa: E402
from bench_ccsds.kvn import CcsdsError  # noqa: E402
from bench_engine.cli.guard import ArgumentParser, check_output, exit_codes, run_main, writing  # noqa: E402
from bench_engine.config import apply_overrides, load_scenario, select_variant  # noqa: E402
from bench_engine.launcher import prepare_run, run_graph  # noqa: E402
from bench_eval.cli.replay import recorded_run  # noqa: E402
from bench_eval.scoring import NothingToScore  # noqa: E402
from bench_eval.summary import score_run  # noqa: E402

EPILOG = exit_codes(
    c0="the TDM was replayed and the estimators' run scored",
    c1="a node failed (named, with the tail of its log), or the estimators published nothing to score",
    c2="bad input, stopped before any node started: a TDM or OEM that cannot be read (the file and line named), "
    "data the scenario cannot take (no ground radar, another time system, epochs before time.start), an "
    "invalid scenario, estimator or --set, or an output directory that cannot be written",
    c124="the replay did not end within its time limit",
)


def main(argv: list[str] | None = None) -> int:
    """Import the TDM of the command line and replay it; the exit codes of EPILOG."""
    p = ArgumentParser(description=__doc__, epilog=EPILOG)
    p.add_argument("tdm", type=Path, help="a CCSDS TDM in KVN (RANGE, ANGLE_1/ANGLE_2 AZEL, DOPPLER_INSTANTANEOUS)")
    p.add_argument("--scenario", required=True, help="registered scenario name or YAML path: station, noise, time")
    p.add_argument("--variant", default=None, help="the scenario's variant(s), comma-separated")
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="scenario override, repeatable (e.g. time.start=0)",
    )
    p.add_argument("--reference", type=Path, default=None, help="an OEM (TEME, UTC) to score the estimates against")
    p.add_argument(
        "--sensor",
        default=None,
        help="the scenario's ground radar to give the data to (default: the "
        "one named like the TDM's PARTICIPANT_1, else the only one)",
    )
    p.add_argument("--estimators", default=None, help="comma-separated estimators (default: the scenario's)")
    p.add_argument("--out", type=Path, default=None, help="output directory (default runs/tdm-TIMESTAMP)")
    p.add_argument("--single-process", action="store_true", help="run every node in this one process")
    p.add_argument("--domain-id", type=int, default=None, help="ROS_DOMAIN_ID (default: the first free one)")
    p.add_argument("--json", action="store_true", help="print the score as JSON")
    args = p.parse_args(argv)
    out = (args.out or Path(f"runs/tdm-{time.strftime('%Y%m%d-%H%M%S')}")).resolve()
    cfg = apply_overrides(select_variant(load_scenario(args.scenario), args.variant), args.overrides)
    check_output(out)
    with writing(out):
        imported = import_tdm(args.tdm, cfg, out / "input" / "bag", args.reference, args.sensor)
        print(imported.summary(), file=sys.stderr)
        run = recorded_run(imported.bag_dir)
        estimators = args.estimators.split(",") if args.estimators else None
        plan = prepare_run(
            run["scenario"]["scenario"],
            out,
            estimators,
            run.get("seed"),
            source="player",
            extra={"replay_bag": str(imported.bag_dir), "ccsds_import": run["ccsds_import"]},
            cfg=run["scenario"],
        )
    print(f"[import] {args.tdm} -> {plan.bag_dir} with {plan.run['estimators']}", file=sys.stderr)
    code = run_graph(plan, args.domain_id, args.single_process, tag="import")
    if code != 0:
        return code
    print(score_run(plan.out, args.json))  # NothingToScore: exit code 1 (command)
    return 0


def command() -> None:
    """Console script ``bench_import_tdm``: ``main`` with its failures told in one line (bench_engine.cli.guard)."""
    sys.exit(run_main(main, expected={CcsdsError: 2, NothingToScore: 1}))
