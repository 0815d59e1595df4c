#!/usr/bin/env python3
"""grace_velocity: every estimator's range-rate residual next to the bounds (issue 19 §1-2), one in-process
run of the scenario (default: variant ``dynamic``, seed 1, 10 s / 2 cm).

Bound (b): the Cramer-Rao bound of each satellite's orbit (state and C_d A / m) under the truth's dynamics from
its GNSS fixes, mapped to the range rate; bound (a): the RTS smoother's covariance under the white-jerk model
with the filter's q (bench_studies.grace_velocity.bounds). Efficiency = bound RMS / residual RMS (vs truth).

Example:
  .venv/bin/python scripts/grace_bounds.py --seed 1
"""
from __future__ import annotations

import argparse
import os
import sys
import time

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import numpy as np

from bench_engine.config import apply_overrides, load_scenario, select_variant
from bench_eval.inprocess_runs import bag_data
from bench_eval.scoring import run_offline, scoring_options
from bench_studies.grace_velocity.bounds import dynamic_bound, smoother_bound
from bench_studies.grace_velocity.metrics import residuals


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x * x)))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--variant", default="dynamic")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--seed", type=int, default=1)
    args = p.parse_args(argv)
    cfg = apply_overrides(select_variant(load_scenario("grace_velocity"), args.variant), args.overrides)
    start = time.perf_counter()
    data = bag_data(cfg, cfg.get("default_filters"), args.seed)
    opts = scoring_options(cfg)
    seconds = {}
    for name, job in opts.offline.items():
        t0 = time.perf_counter()
        run_offline(data, type(opts)(opts.metric, opts.options, {name: job}))
        seconds[name] = time.perf_counter() - t0
    skip = opts.options["skip_s"]
    t_b, sd_b = dynamic_bound(data)
    first = min(t for t, _ in data.truth.values())
    bound_b = _rms(sd_b[t_b - first >= skip])
    rts = data.estimates["kf_a_rts"]
    sd_a = smoother_bound(rts, opts.options["baseline"])
    bound_a = _rms(sd_a[rts.t - first >= skip])
    print(f"grace_velocity seed {args.seed} ({args.variant or 'default'}): range-rate residual [um/s], "
          f"after {skip:g} s")
    print(f"bound (a) white-jerk q (RTS covariance): {bound_a * 1e6:.3f}; bound (b) truth's dynamics: "
          f"{bound_b * 1e6:.4f}")
    print(f"{'estimator':14} {'RMS vs truth':>13} {'std vs KBR':>11} {'eff. (b)':>9} {'eff. (a)':>9} {'time [s]':>9}")
    for name in [*cfg.get("default_filters", []), *opts.offline]:
        r = residuals(data, name, opts.options)
        if r is None:
            continue
        rms = _rms(r["truth"])
        print(f"{name:14} {rms * 1e6:13.3f} {np.std(r['kbr']) * 1e6:11.3f} {bound_b / rms:9.3g} {bound_a / rms:9.3g} "
              f"{seconds.get(name, float('nan')):9.1f}")
    print(f"total {time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
