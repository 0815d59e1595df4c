#!/usr/bin/env python3
"""The command bench_import_tdm run from the repository: same flags, output and exit codes. Its logic, options
and examples: bench_ccsds/cli/import_tdm.py (or --help)."""

from bench_ccsds.cli.import_tdm import command

if __name__ == "__main__":
    command()
