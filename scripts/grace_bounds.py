#!/usr/bin/env python3
"""grace_velocity: every estimator's range-rate residual next to the bounds (issue 19 §1-2), one in-process
run of the scenario (default: variant ``dynamic``, seed 1, 10 s / 2 cm).

Bound (b): the Cramer-Rao bound of each satellite's orbit (state and C_d A / m) under the truth's dynamics from
its GNSS fixes, mapped to the range rate; bound (a): the RTS smoother's covariance under the white-jerk model
with the filter's q (bench_studies.grace_velocity.bounds). Efficiency = bound RMS / residual RMS (vs truth).
With --out DIR it also draws DIR/grace_velocity_bounds.png: each estimator's range-rate error against the truth,
RMS over 30-minute windows through the day, with the square roots of both bounds over the same windows dashed.

Example:
  .venv/bin/python scripts/grace_bounds.py --seed 1 --out runs/grace_bounds
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import numpy as np

from bench_engine.config import apply_overrides, load_scenario, select_variant
from bench_engine.scenario import default_estimators
from bench_engine.settings import replaced
from bench_eval.inprocess_runs import bag_data
from bench_eval.report import BOUND_STYLE, Plot, save_plot
from bench_eval.scoring import run_offline, scoring_options
from bench_studies.grace_velocity.bounds import dynamic_bound, smoother_bound
from bench_studies.grace_velocity.metrics import residuals
from bench_studies.grace_velocity.report import MM, rolling_rms

FIGURE = "grace_velocity_bounds.png"
WINDOW_S = 1800.0


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x * x)))


def draw_bounds_figure(out: Path, errors: dict[str, tuple[np.ndarray, np.ndarray]],
                       bounds: dict[str, tuple[np.ndarray, np.ndarray]]) -> Path:
    """OUT/FIGURE: each estimator's range-rate error against the truth and each bound's standard deviation, as
    RMS over WINDOW_S windows (t in s from the first fix, values in m/s), on a log scale."""
    def draw(fig) -> None:
        ax = fig.subplots()
        for name, (t, err) in errors.items():
            tc, rms = rolling_rms(t, err, WINDOW_S)
            ax.semilogy(tc / 3600.0, rms * MM, lw=1.0, marker=".", ms=3, label=name)
        for (name, (t, sd)), ls in zip(bounds.items(), (BOUND_STYLE["ls"], (0, (2, 2)))):
            tc, rms = rolling_rms(t, sd, WINDOW_S)
            ax.semilogy(tc / 3600.0, rms * MM, **{**BOUND_STYLE, "ls": ls}, label=f"√{name}")
        ax.set_xlabel("time [h]")
        ax.set_ylabel(f"range-rate error vs truth, RMS over {WINDOW_S / 60:g} min [mm/s]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, ncol=4)

    out.mkdir(parents=True, exist_ok=True)
    return save_plot(out, Plot(FIGURE, "grace_velocity: range-rate error against the truth next to bounds (a) and "
                                       "(b)", draw, (10.0, 5.5)))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--variant", default="dynamic")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--out", type=Path, default=None, help=f"write {FIGURE} (the errors and bounds over the day) here")
    args = p.parse_args(argv)
    cfg = apply_overrides(select_variant(load_scenario("grace_velocity"), args.variant), args.overrides)
    start = time.perf_counter()
    data = bag_data(cfg, default_estimators(cfg), args.seed)
    opts = scoring_options(cfg)
    seconds = {}
    for name, job in opts.offline.items():
        t0 = time.perf_counter()
        run_offline(data, replaced(opts, offline={name: job}))
        seconds[name] = time.perf_counter() - t0
    skip = opts.options.skip_s
    t_b, sd_b = dynamic_bound(data)
    first = min(t for t, _ in data.truth.values())
    late_b = t_b - first >= skip
    bound_b = _rms(sd_b[late_b])
    rts = data.estimates["kf_a_rts"]
    sd_a = smoother_bound(rts, opts.options.baseline)
    late_a = rts.t - first >= skip
    bound_a = _rms(sd_a[late_a])
    print(f"grace_velocity seed {args.seed} ({args.variant or 'default'}): range-rate residual [um/s], "
          f"after {skip:g} s")
    print(f"bound (a) white-jerk q (RTS covariance): {bound_a * 1e6:.3f}; bound (b) truth's dynamics: "
          f"{bound_b * 1e6:.4f}")
    print(f"{'estimator':14} {'RMS vs truth':>13} {'std vs KBR':>11} {'eff. (b)':>9} {'eff. (a)':>9} {'time [s]':>9}")
    errors = {}
    for name in [*(default_estimators(cfg) or []), *opts.offline]:
        r = residuals(data, name, opts.options)
        if r is None:
            continue
        errors[name] = (r["t"], r["truth"])
        rms = _rms(r["truth"])
        print(f"{name:14} {rms * 1e6:13.3f} {np.std(r['kbr']) * 1e6:11.3f} {bound_b / rms:9.3g} {bound_a / rms:9.3g} "
              f"{seconds.get(name, float('nan')):9.1f}")
    print(f"total {time.perf_counter() - start:.0f} s")
    if args.out is not None:
        path = draw_bounds_figure(args.out, errors, {"bound (b)": (t_b[late_b] - first, sd_b[late_b]),
                                                     "bound (a)": (rts.t[late_a] - first, sd_a[late_a])})
        print(f"figure: {path}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
