"""Export a bag to CCSDS Navigation Data Messages (KVN): every estimator's track and the truth as an OEM with
covariance blocks, every sensor's measurements as a TDM. Frames and time: REF_FRAME TEME (the bench's eci on the
calendar), TIME_SYSTEM UTC, the run's epoch (time.epoch, else the nominal epoch: bench_ccsds/epochs.py). What
CCSDS has no keyword for is listed, not written.

Examples:
  .venv/bin/python scripts/export.py runs/iss/bag --out runs/iss/ccsds
  .venv/bin/python scripts/export.py runs/demo/leo_radar/bag --out runs/ccsds --estimators ukf --no-truth
"""

from __future__ import annotations

import sys
from pathlib import Path

from bench_ccsds.export import export_bag
from bench_ccsds.kvn import CcsdsError
from bench_engine.cli.guard import ArgumentParser, check_output, exit_codes, run_main, writing

EPILOG = exit_codes(
    c0="the messages were written (the summary lists each file, and what was not exported)",
    c2="bad input: a directory that is not a bag recorded by this bench, a damaged bag, an estimator "
    "the bag has no estimates of, or an output directory that cannot be written",
)


def main(argv: list[str] | None = None) -> int:
    """Export the bag of the command line; the exit codes of EPILOG."""
    p = ArgumentParser(description=__doc__, epilog=EPILOG)
    p.add_argument("bag", type=Path, help="bag directory recorded by launch.py / montecarlo.py / replay.py")
    p.add_argument("--out", type=Path, default=None, help="output directory (default: BAG/../ccsds)")
    p.add_argument("--estimators", default=None, help="comma-separated estimators to export (default: all)")
    p.add_argument("--no-truth", action="store_true", help="do not export the truth")
    args = p.parse_args(argv)
    out = args.out or args.bag.resolve().parent / "ccsds"
    check_output(out)
    with writing(out):
        result = export_bag(
            args.bag, out, args.estimators.split(",") if args.estimators else None, truth=not args.no_truth
        )
    print(result.summary())
    return 0


def command() -> None:
    """Console script ``bench_export``: ``main`` with its failures told in one line (bench_engine.cli.guard)."""
    sys.exit(run_main(main, expected={CcsdsError: 2}))
