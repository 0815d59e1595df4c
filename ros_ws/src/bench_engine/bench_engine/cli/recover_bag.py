"""Rebuild bags a crashed recorder left incomplete (no metadata.yaml, no MCAP summary) into complete rosbag2
bags, keeping every message up to the last flushed chunk (bench_engine.recovery). The damaged file is kept
as NAME.mcap.truncated (with --force, a metadata.yaml that cannot be read as NAME.yaml.damaged). score.py,
replay.py and the launcher do this on their own when they meet such a bag.

Examples:
  .venv/bin/python scripts/recover_bag.py runs/crashed/bag
  .venv/bin/python scripts/recover_bag.py runs/mc/run_*/bag --force
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import yaml

from bench_engine import yamlio
from bench_engine.bag_errors import BagUnrecoverable
from bench_engine.cli.guard import ArgumentParser, exit_codes, file_error_in, os_error_line, run_main
from bench_engine.recovery import needs_recovery, recover

EPILOG = exit_codes(
    c0="every bag is complete (recovered, or already)",
    c2="a bag could not be recovered (each named, the others are still recovered): not a bag directory, no "
    ".mcap file, not even the MCAP header readable, or a directory that cannot be written (read-only, no "
    "space left)",
)


def set_aside_unreadable_metadata(bag: Path) -> None:
    """With --force: a metadata.yaml that is not YAML is kept as metadata.yaml.damaged, and the bag is rebuilt
    from its .mcap file alone (recovery reads the old metadata for its custom_data)."""
    metadata = bag / "metadata.yaml"
    if not metadata.is_file():
        return
    try:
        yamlio.load(metadata.read_text(encoding="utf-8"))
    except (yaml.YAMLError, UnicodeDecodeError):
        os.replace(metadata, metadata.with_name("metadata.yaml.damaged"))
        print(f"{bag}: metadata.yaml is not YAML: kept as metadata.yaml.damaged", file=sys.stderr)


def recover_one(bag: Path, force: bool) -> str | None:
    """Recover one bag; None when done, else the one-line error."""
    if not bag.is_dir():
        return f"{bag} is not a directory: give a bag directory (metadata.yaml and .mcap file)"
    if not any(bag.glob("*.mcap")):
        return f"{bag}: no .mcap file: not a bag directory, nothing to recover"
    if not (force or needs_recovery(bag)):
        print(f"{bag}: complete, nothing to do", file=sys.stderr)
        return None
    try:
        if force:
            set_aside_unreadable_metadata(bag)
        print(recover(bag).summary())
    except BagUnrecoverable as err:
        return str(err)
    except (OSError, RuntimeError) as err:  # RuntimeError: the bag writer's, raised from its OSError
        cause = file_error_in(err)
        if cause is None:
            raise
        if cause.filename is None:
            cause.filename = str(bag)
        return os_error_line(cause)
    return None


def main(argv: list[str] | None = None) -> int:
    """Recover the bags of the command line; the exit codes of EPILOG."""
    p = ArgumentParser(description=__doc__, epilog=EPILOG)
    p.add_argument("bags", nargs="+", type=Path, help="bag directories")
    p.add_argument(
        "--force",
        action="store_true",
        help="rebuild a bag even if it has a metadata.yaml (e.g. a damaged file with one)",
    )
    args = p.parse_args(argv)
    code = 0
    for bag in args.bags:
        error = recover_one(bag, args.force)
        if error is not None:
            print(f"error: {' '.join(error.split())}", file=sys.stderr)
            code = 2
    return code


def command() -> None:
    """Console script ``bench_recover_bag``: ``main`` with its failures told in one line (bench_engine.cli.guard)."""
    sys.exit(run_main(main))
