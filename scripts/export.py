#!/usr/bin/env python3
"""The command bench_export run from the repository: same flags, output and exit codes. Its logic, options and
examples: bench_ccsds/cli/export.py (or --help)."""

from bench_ccsds.cli.export import command

if __name__ == "__main__":
    command()
