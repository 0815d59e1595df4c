#!/usr/bin/env python3
"""Like-for-like tuning of grace_velocity's methods (issue 19 §2): each method's free parameter is the one
with the smallest range-rate RMS against the truth on a tuning seed (default 1001), never a scored seed, over
the scenario's scoring window (the central day, as the scorer scores it: bench_eval.window; an orbit fit to the
first --span-s seconds is scored over that arc's window) (bench_studies.grace_velocity.tuning). The chosen
values go into scenario.yaml.

Example:
  .venv/bin/python scripts/grace_tune_methods.py --methods rts,savgol,orbit_fit_j2
"""

from __future__ import annotations

import argparse
import os
import sys

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

from bench_engine.config import ScenarioError, apply_overrides, load_scenario, select_variant
from bench_engine.settings import read
from bench_studies.grace_velocity.pair_fit import PairFitParameters
from bench_studies.grace_velocity.tuning import (
    EMPIRICAL_SIGMAS,
    RTS_QS,
    SAVGOL_DEGREES,
    SAVGOL_WINDOWS_S,
    TUNING_SEED,
    measurements,
    orbit_fit_score,
    rts_score,
    savgol_score,
    window_of,
)


def _csv(values) -> str:
    return ",".join(f"{v:g}" for v in values)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--variant", default=None)
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--seed", type=int, default=TUNING_SEED)
    p.add_argument("--methods", default="rts,savgol,orbit_fit_j2")
    p.add_argument("--qs", default=_csv(RTS_QS), help="RTS white-jerk densities q [m^2/s^5]")
    p.add_argument("--windows", default=_csv(sorted(SAVGOL_WINDOWS_S)), help="Savitzky-Golay windows [s]")
    p.add_argument("--orders", default=_csv(SAVGOL_DEGREES), help="Savitzky-Golay degrees")
    p.add_argument("--sigmas", default=_csv(EMPIRICAL_SIGMAS), help="orbit_fit_j2's empirical sigmas [m/s^2]")
    p.add_argument("--span-s", type=float, default=21600.0, help="orbit fits to the first span_s seconds")
    args = p.parse_args(argv)
    try:
        cfg = apply_overrides(select_variant(load_scenario("grace_velocity"), args.variant), args.overrides)
        window = window_of(cfg)
    except ScenarioError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    items, truth = measurements(cfg, args.seed)
    methods = args.methods.split(",")
    print(
        f"tuning seed {args.seed}: range-rate RMS against the truth [um/s], the scoring window (the arc less "
        f"{window.head_s:g} s at its start and {window.tail_s:g} s at its end)",
        flush=True,
    )
    if "rts" in methods:
        scores = {q: rts_score(cfg, "kf_a", float(q), items, truth, window) for q in args.qs.split(",")}
        for q, s in scores.items():
            print(f"  kf_a_rts q={q}: {s * 1e6:.3f}", flush=True)
        print(f"chosen kf_a_rts q = {min(scores, key=scores.get)}", flush=True)
    if "savgol" in methods:
        scores = {
            (w, o): savgol_score(items, truth, float(w), int(o), window)
            for w in args.windows.split(",")
            for o in args.orders.split(",")
        }
        for (w, o), s in scores.items():
            print(f"  savgol window {w} s, degree {o}: {s * 1e6:.3f}", flush=True)
        print(f"chosen savgol (window_s, polyorder) = {min(scores, key=scores.get)}", flush=True)
    if "orbit_fit_j2" in methods:
        base = cfg["variants"]["dynamic"]["scoring.offline.orbit_fit_j2"]["params"]
        scores = {}
        for sigma in args.sigmas.split(","):
            params = read(PairFitParameters, {**base, "empirical_sigma": float(sigma)}, "orbit_fit_j2.params")
            scores[sigma] = orbit_fit_score(cfg, params, items, truth, window, args.span_s)
            print(f"  orbit_fit_j2 empirical_sigma={sigma}: {scores[sigma] * 1e6:.3f}", flush=True)
        print(f"chosen orbit_fit_j2 empirical_sigma = {min(scores, key=scores.get)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
