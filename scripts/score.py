#!/usr/bin/env python3
"""The command bench_score run from the repository: same flags, output and exit codes. Its logic, options and
examples: bench_eval/cli/score.py (or --help)."""

from bench_eval.cli.score import command

if __name__ == "__main__":
    command()
