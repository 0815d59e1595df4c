#!/usr/bin/env python3
"""Choose grace_velocity's white-jerk density q from the GNSS baselines alone (innovation likelihood), and
show it against the q the truth and the KBR would have chosen over the scenario's scoring window
(bench_studies.grace_velocity.tuning).

Runs the truth and the sensors in process once, then the filter over the same measurements for every q of
the grid. The scenario's default q is the likelihood's choice on the default scenario and the tuning seed (1001,
never a scored one).

Examples:
  .venv/bin/python scripts/grace_tune_q.py
  .venv/bin/python scripts/grace_tune_q.py --variant gnss60 --qs 1e-8,1e-7,1e-6,1e-5 --seed 2
"""

from __future__ import annotations

import argparse
import os
import sys

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

from bench_engine.config import ScenarioError, apply_overrides, load_scenario, select_variant
from bench_studies.grace_velocity.tuning import TUNING_SEED, choices, scan

DEFAULT_QS = "1e-15,1e-14,1e-13,1e-12,1e-11,1e-10,1e-9,3e-9,1e-8,3e-8,1e-7,3e-7,1e-6,3e-6,1e-5,3e-5,1e-4"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scenario", default="grace_velocity", help="scenario name or YAML path")
    p.add_argument("--variant", default=None, help="variants applied in order (comma-separated)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--filter", default="kf_a", help="the filter whose q is chosen (default kf_a)")
    p.add_argument("--qs", default=DEFAULT_QS, help="grid of q [m^2/s^5], comma-separated")
    p.add_argument("--seed", type=int, default=TUNING_SEED)
    args = p.parse_args(argv)
    try:
        qs = [float(q) for q in args.qs.split(",")]
        cfg = apply_overrides(select_variant(load_scenario(args.scenario), args.variant), args.overrides)
        scores = scan(cfg, args.filter, qs, args.seed)
    except (ScenarioError, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(f"{'q [m^2/s^5]':>12} {'log-likelihood':>16} {'velocity RMSE [mm/s]':>21} {'rr - KBR std [mm/s]':>20}")
    for s in scores:
        print(f"{s.q:12.3g} {s.loglik:16.2f} {s.velocity_rmse * 1e3:21.4f} {s.rr_kbr_std * 1e3:20.5f}")
    for criterion, s in choices(scores).items():
        print(f"best by {criterion}: q = {s.q:.3g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
