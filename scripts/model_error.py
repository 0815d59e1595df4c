#!/usr/bin/env python3
"""Unmodelled acceleration of each filter's relative-motion model against the scenario's nonlinear truth
(bench_studies.formation_cqkf.model_error): per model and LVLH axis the RMS and maximum residual acceleration,
and the RMS one-step position prediction error over 1 s and 10 s.

Cases: the scenario as configured, or one case per --variant (comma-separated variants applied in order),
or every distinct truth of a sweep grid (--grid, see bench_eval.sweep).

Examples:
  .venv/bin/python scripts/model_error.py formation_cqkf --grid tables
  .venv/bin/python scripts/model_error.py formation_cqkf --variant "" --variant e0005,size10km --json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from bench_engine.config import ScenarioError, apply_overrides, load_scenario, select_variant
from bench_eval.sweep import distinct_truths, load_grid
from bench_studies.formation_cqkf.model_error import markdown, model_error_rows


def cases_from_args(args: argparse.Namespace) -> list[tuple[str, dict]]:
    """(label, resolved config) per case: the grid's distinct truths, each --variant, or the scenario."""
    if args.grid:
        return distinct_truths(load_grid(args.scenario, args.grid, args.overrides))
    base = load_scenario(args.scenario)
    variants = args.variant if args.variant is not None else [""]
    return [(v or "default", apply_overrides(select_variant(base, v), args.overrides)) for v in variants]


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenario", help="scenario name or YAML path (a formation scenario)")
    p.add_argument(
        "--variant",
        action="append",
        default=None,
        metavar="V1,V2",
        help='one case: variants applied in order (repeatable; "" = the scenario as is)',
    )
    p.add_argument("--grid", help="one case per distinct truth of this sweep grid (the scenario's 'sweeps')")
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="scenario override applied to every case, repeatable",
    )
    p.add_argument("--out", type=Path, help="write model_error.md and model_error.json into this directory")
    p.add_argument("--json", action="store_true", help="print the rows as JSON instead of Markdown")
    args = p.parse_args(argv)
    if args.grid and args.variant is not None:
        p.error("give either --grid or --variant, not both")
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        rows = [row for label, cfg in cases_from_args(args) for row in model_error_rows(label, cfg)]
    except ScenarioError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    table = markdown(rows)
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "model_error.md").write_text(table + "\n")
        (args.out / "model_error.json").write_text(json.dumps(rows, indent=1))
    print(json.dumps(rows, indent=1) if args.json else table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
