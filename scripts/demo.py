#!/usr/bin/env python3
"""The command bench_demo run from the repository: same flags, output and exit codes. Its logic, options and
examples: bench_eval/cli/demo.py (or --help)."""

from bench_eval.cli.demo import command

if __name__ == "__main__":
    command()
