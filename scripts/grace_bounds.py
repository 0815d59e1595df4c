#!/usr/bin/env python3
"""grace_velocity: every estimator's range-rate residual next to the bounds (issue 19 §1-2), one in-process
run of the scenario (default: variant ``dynamic``, seed 1, 10 s / 2 cm).

Bound (b): the Cramer-Rao bound of each satellite's orbit (state and C_d A / m) under the truth's dynamics from
its GNSS fixes, mapped to the range rate; bound (a): the RTS smoother's covariance under the white-jerk model
with the filter's q (bench_studies.grace_velocity.bounds). Efficiency = bound RMS / residual RMS (vs truth).
Every figure is over the scenario's scoring window (the central day, every estimator over the same steps:
bench_eval.window), and beside it each estimator's RMS over the arc's first and last margins (head, tail), where
smoothers and fits have data on one side only. With --out DIR it also draws DIR/grace_velocity_bounds.png: each
estimator's range-rate error against the truth, RMS over 30-minute windows through the whole arc (the margins
shaded), with the square roots of both bounds over the same windows dashed.

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
from bench_eval.scoring import run_offline, scored_estimators, scoring_options
from bench_eval.window import ScoringWindow
from bench_studies.grace_velocity.bounds import dynamic_bound, smoother_bound
from bench_studies.grace_velocity.metrics import residuals
from bench_studies.grace_velocity.report import MM, rolling_rms

FIGURE = "grace_velocity_bounds.png"
WINDOW_S = 1800.0


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x * x))) if len(x) else float("nan")


def draw_bounds_figure(
    out: Path,
    errors: dict[str, tuple[np.ndarray, np.ndarray]],
    bounds: dict[str, tuple[np.ndarray, np.ndarray]],
    day: tuple[float, float],
) -> Path:
    """OUT/FIGURE: each estimator's range-rate error against the truth and each bound's standard deviation, as
    RMS over WINDOW_S windows (t in s from the run's start, values in m/s), on a log scale; outside ``day`` (the
    scoring window, s) shaded."""

    def draw(fig) -> None:
        ax = fig.subplots()
        for name, (t, err) in errors.items():
            tc, rms = rolling_rms(t, err, WINDOW_S)
            ax.semilogy(tc / 3600.0, rms * MM, lw=1.0, marker=".", ms=3, label=name)
        for (name, (t, sd)), ls in zip(bounds.items(), (BOUND_STYLE["ls"], (0, (2, 2)))):
            tc, rms = rolling_rms(t, sd, WINDOW_S)
            ax.semilogy(tc / 3600.0, rms * MM, **{**BOUND_STYLE, "ls": ls}, label=f"√{name}")
        end = max(float(t[-1]) for t, _ in errors.values())
        for a, b in ((0.0, day[0]), (day[1], end)):
            if b > a:
                ax.axvspan(a / 3600.0, b / 3600.0, color="0.85", zorder=0)
        ax.set_xlabel("time [h] (shaded: the arc's margins, not scored)")
        ax.set_ylabel(f"range-rate error vs truth, RMS over {WINDOW_S / 60:g} min [mm/s]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, ncol=4)

    out.mkdir(parents=True, exist_ok=True)
    return save_plot(
        out,
        Plot(
            FIGURE, "grace_velocity: range-rate error against the truth next to bounds (a) and (b)", draw, (10.0, 5.5)
        ),
    )


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--variant", default="dynamic")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--out", type=Path, default=None, help=f"write {FIGURE} (the errors and bounds over the arc) here")
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
    window = opts.window or ScoringWindow()
    scored = scored_estimators(data, list(opts.offline))
    day, scored = window.cut(data, scored)
    edges = {edge: window.cut(data, scored, edge)[0] for edge in ("head", "tail")}
    times = np.array([t for t, _ in data.truth.values()])
    first, last = times.min(), times.max()
    t_b, sd_b = dynamic_bound(data)
    in_day = window.inside(t_b, first, last)
    bound_b = _rms(sd_b[in_day])
    rts = day.estimates["kf_a_rts"]
    sd_a = smoother_bound(rts, opts.options.baseline)
    bound_a = _rms(sd_a)
    steps = len(rts.steps)
    print(
        f"grace_velocity seed {args.seed} ({args.variant or 'default'}): range-rate residual [um/s] over the "
        f"scoring window [{window.head_s:g}, {last - first - window.tail_s:g}] s ({steps} steps, the same for "
        f"every estimator); head / tail: the first {window.head_s:g} s / last {window.tail_s:g} s of the arc"
    )
    print(
        f"bound (a) white-jerk q (RTS covariance): {bound_a * 1e6:.3f}; bound (b) truth's dynamics: {bound_b * 1e6:.4f}"
    )
    print(
        f"{'estimator':14} {'RMS vs truth':>13} {'std vs KBR':>11} {'eff. (b)':>9} {'eff. (a)':>9} {'head RMS':>11} "
        f"{'tail RMS':>11} {'time [s]':>9}"
    )
    errors = {}
    for name in [n for n in [*(default_estimators(cfg) or []), *opts.offline] if n in scored]:
        r = residuals(day, name, opts.options)
        whole = residuals(data, name, opts.options)
        if r is None or whole is None:
            continue
        errors[name] = (whole["t"], whole["truth"])
        ends = [residuals(edges[e], name, opts.options) for e in ("head", "tail")]
        head, tail = (_rms(x["truth"]) if x is not None else float("nan") for x in ends)
        rms = _rms(r["truth"])
        print(
            f"{name:14} {rms * 1e6:13.3f} {np.std(r['kbr']) * 1e6:11.3f} {bound_b / rms:9.3g} {bound_a / rms:9.3g} "
            f"{head * 1e6:11.1f} {tail * 1e6:11.1f} {seconds.get(name, float('nan')):9.1f}"
        )
    print(f"total {time.perf_counter() - start:.0f} s")
    if args.out is not None:
        rts_all = data.estimates["kf_a_rts"]
        path = draw_bounds_figure(
            args.out,
            errors,
            {
                "bound (b)": (t_b - first, sd_b),
                "bound (a)": (rts_all.t - first, smoother_bound(rts_all, opts.options.baseline)),
            },
            (window.head_s, last - first - window.tail_s),
        )
        print(f"figure: {path}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
