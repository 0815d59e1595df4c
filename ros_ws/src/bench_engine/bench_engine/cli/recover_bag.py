"""Rebuild bags a crashed recorder left incomplete (no metadata.yaml, no MCAP summary) into complete rosbag2
bags, keeping every message up to the last flushed chunk (bench_engine.recovery). The damaged file is kept
as NAME.mcap.truncated. score.py, replay.py and the launcher do this on their own when they meet such a bag.

Examples:
  .venv/bin/python scripts/recover_bag.py runs/crashed/bag
  .venv/bin/python scripts/recover_bag.py runs/mc/run_*/bag --force
Exit code: 0 when every bag is complete (recovered or already), 2 when one cannot be recovered.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bench_engine.recovery import BagUnrecoverable, needs_recovery, recover


def main(argv: list[str] | None = None) -> int:
    """Recover the bags of the command line; 0 when all are complete, 2 when one cannot be recovered."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("bags", nargs="+", type=Path, help="bag directories")
    p.add_argument("--force", action="store_true",
                   help="rebuild a bag even if it has a metadata.yaml (e.g. a damaged file with one)")
    args = p.parse_args(argv)
    code = 0
    for bag in args.bags:
        if not (args.force or needs_recovery(bag)):
            print(f"{bag}: complete, nothing to do", file=sys.stderr)
            continue
        try:
            print(recover(bag).summary())
        except BagUnrecoverable as err:
            print(f"error: {err}", file=sys.stderr)
            code = 2
    return code


def command() -> None:
    """Console script ``bench_recover_bag``."""
    sys.exit(main())
