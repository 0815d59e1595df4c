#!/usr/bin/env python3
"""The command bench_replay run from the repository: same flags, output and exit codes. Its logic, options and
examples: bench_eval/cli/replay.py (or --help)."""

from bench_eval.cli.replay import command

if __name__ == "__main__":
    command()
