"""Paper 001's figures from a formation_pf Monte Carlo's bags, beyond the generic scores: per filter the worst
absolute error per axis over every run and every step after the settling time, the runs meeting the claim,
settling times, NEES and 3-sigma fractions, and the particle filters' N_eff, resampling and Gauss-Newton
diagnostics. Axes are the bench's LVLH (x radial, y along-track, z orbit normal).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from bench_engine.labels import ORBIT
from bench_eval import metrics
from bench_eval.scoring import load_bags, scoring_options, track_of

CONFIGS = ("default", "range_0p5m", "j2_truth", "euler_phi")
AXES = ORBIT


def filter_figures(
    tracks: list[metrics.Track],
    diags: list[dict[str, np.ndarray]],
    scored: dict,
    settle_s: float,
    pos_thr: float,
    vel_thr: float,
) -> dict:
    late = [np.abs(tr.error(AXES))[tr.t - tr.t[0] >= settle_s] for tr in tracks]
    worst = np.max(np.concatenate(late), axis=0)
    thresholds = np.array([pos_thr] * 3 + [vel_thr] * 3)
    claim = sum(bool(np.all(e <= thresholds)) for e in late)
    per_run_settle = [metrics.settling_time(tr.t, np.abs(tr.error(AXES)), thresholds) for tr in tracks]
    # the first estimate is the prior (the filter node initialises on the first measurement): skip it
    n_eff = np.array([d["n_eff"][1:] for d in diags])
    out = {
        "runs": len(tracks),
        "max_abs_error_after": dict(zip(AXES, worst.tolist())),
        "claim_runs": claim,
        "settling_time_s": scored["settling_time_s"],
        "settling_time_worst_run_s": None if np.any(np.isnan(per_run_settle)) else float(max(per_run_settle)),
        "nees_mean": scored["nees_mean"],
        "nees_bounds": scored["nees_bounds"],
        "nees_fraction_inside": scored["nees_fraction_inside"],
        "within_3sigma_min": min(scored["within_3sigma"].values()),
        "n_eff_first_update": float(np.median(n_eff[:, 0])),
        "n_eff_median_after": float(np.median(n_eff[:, 1:])),
        "n_eff_min_after": float(np.min(n_eff[:, 1:])),
        "resampled_pct": float(100.0 * np.mean([d["resampled"][1:] for d in diags])),
    }
    if all("gn_passes" in d for d in diags):
        passes = np.array([d["gn_passes"][1:] for d in diags])
        out["gn_passes_first_update_max"] = float(passes[:, 0].max())
        out["gn_passes_after_mean"] = float(passes[:, 1:].mean())
    return out


def tabulate(run_dir: Path, settle_s: float) -> dict[str, dict]:
    scored = json.loads((run_dir / "score.json").read_text())
    bags = sorted(p.parent for p in run_dir.glob("run_*/bag/metadata.yaml"))
    runs = load_bags(bags)
    opts = scoring_options(runs[0].scenario).options
    out = {}
    for name in runs[0].run["estimators"]:
        tracks = [track_of(d, name) for d in runs]
        diags = [d.estimates[name].diagnostics for d in runs]
        out[name] = filter_figures(
            tracks, diags, scored["estimators"][name], settle_s, opts.position_threshold, opts.velocity_threshold
        )
    return out


def print_table(config: str, figures: dict[str, dict], settle_s: float) -> None:
    print(f"\n== {config} ==  max |error| over runs and t >= {settle_s:g} s; claim: runs under 0.5 m / 0.02 m/s")
    print(
        f"{'filter':<6}" + "".join(f"{a:>9}" for a in AXES) + f"{'claim':>7} {'settle (worst)':>15} "
        f"{'NEES [band] inside':>27} {'3 sigma':>8} {'N_eff 1st/med/min':>19} {'resampled':>10}"
    )
    for name, f in figures.items():
        settle = "never" if f["settling_time_s"] is None else f"{f['settling_time_s']:.0f} s"
        worst = "never" if f["settling_time_worst_run_s"] is None else f"{f['settling_time_worst_run_s']:.0f} s"
        lo, hi = f["nees_bounds"]
        print(
            f"{name:<6}"
            + "".join(f"{f['max_abs_error_after'][a]:9.3g}" for a in AXES)
            + f"{f['claim_runs']:>4}/{f['runs']:<2} {settle:>6} ({worst:>6}) "
            f"{f['nees_mean']:9.3g} [{lo:.2f}, {hi:.2f}] {100 * f['nees_fraction_inside']:3.0f} % "
            f"{100 * f['within_3sigma_min']:6.0f} % {f['n_eff_first_update']:7.0f}/{f['n_eff_median_after']:5.0f}"
            f"/{f['n_eff_min_after']:5.0f} {f['resampled_pct']:8.1f} %"
        )
        if "gn_passes_after_mean" in f:
            print(
                f"{'':<6}Gauss-Newton passes: first update max {f['gn_passes_first_update_max']:.0f}, "
                f"afterwards mean {f['gn_passes_after_mean']:.3f}"
            )
