#!/usr/bin/env python3
"""The command bench_recover_bag run from the repository: same flags, output and exit codes. Its logic, options and
examples: bench_engine/cli/recover_bag.py (or --help)."""

from bench_engine.cli.recover_bag import command

if __name__ == "__main__":
    command()
