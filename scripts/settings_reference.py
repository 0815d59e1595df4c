#!/usr/bin/env python3
"""The settings reference: every scenario key with its type, default, unit and meaning, generated from the code
that reads it. Its logic and options: bench_engine/settings_reference.py (or --help)."""

import sys

from bench_engine.settings_reference import main

if __name__ == "__main__":
    sys.exit(main())
