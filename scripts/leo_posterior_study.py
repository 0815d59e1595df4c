#!/usr/bin/env python3
"""How consistent can any estimator be early in the leo_radar pass? The filters against the exact posterior.

With 1 deg angles the first scans leave a posterior that is far from Gaussian (curved range shell, ring of
cross-range speeds). This study measures, on identical measurements per seed and at chosen times after the
first scan, the NEES (6 dof; mean over runs, with the runs' 95 % chi-square band) of:
  the scenario's filters (default: its ``ekf`` and ``ukf``), stepped in process as in the graph;
  the batch MAP with its Laplace covariance (Gauss-Newton over every scan; relinearisation.PassBatch);
  the exact posterior's mean and covariance, by adaptive importance sampling
  (tracker_filters/posterior_sampling.py) - the reference any consistent estimator must match.
A Gaussian filter can only be consistent where the Laplace approximation is; where only the sampled
posterior is, consistency needs a sample-based estimator.

Examples:
  .venv/bin/python scripts/leo_posterior_study.py                        # 20 runs, 2/5/10/20/40 s
  .venv/bin/python scripts/leo_posterior_study.py --runs 40 --jobs 2 --times 1,3,10,30,60 --json out.json
  .venv/bin/python scripts/leo_posterior_study.py --filters ekf_paper,ukf_paper --plot nees.png
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads: one BLAS thread per worker

import numpy as np  # noqa: E402
from scipy.stats import chi2  # noqa: E402
from tqdm import tqdm  # noqa: E402

from bench_engine.config import ScenarioError, load_scenario  # noqa: E402
from orbit_sim.truth import build_truth  # noqa: E402
from radar_sensor.sensor import build_sensor  # noqa: E402
from tracker_filters.builders import build_filter_stack  # noqa: E402
from tracker_filters.posterior_sampling import adaptive_posterior  # noqa: E402
from tracker_filters.relinearisation import PassBatch  # noqa: E402

LAPLACE, SAMPLED = "batch MAP (Laplace)", "exact posterior (sampled)"


def nees(x: np.ndarray, P: np.ndarray, truth: np.ndarray) -> float:
    e = x - truth
    return float(e @ np.linalg.solve(P, e))


def one_run(job: dict) -> dict:
    """NEES of every estimator at each requested time for one seed (module docstring)."""
    times = job["times"]
    cfg = load_scenario("leo_radar", job["overrides"] + [f"time.duration={max(times) + 1.0}"])
    truth, sensor = build_truth(cfg), build_sensor(cfg, "radar")
    stacks = {name: build_filter_stack(cfg, name) for name in job["filters"]}
    rng, sampler_rng = np.random.default_rng(job["seed"]), np.random.default_rng([job["seed"], 1])
    out = {name: [] for name in [*job["filters"], LAPLACE, SAMPLED]}
    out["ess"], batch, t0 = [], None, None
    for k, (t, x) in enumerate(zip(truth.grid.times(), truth.states)):
        z = sensor.observe(x, t, k, rng)
        if z is None:
            continue
        for stack in stacks.values():
            if stack.filter.initialised:
                stack.filter.process(t, z, sensor.R, sensor.model)
            else:
                stack.filter.initialise(*stack.initialise(z, sensor.R, sensor, t), t)
        if batch is None:
            first = next(iter(stacks.values())).filter
            batch, t0, post = PassBatch(first.dynamics, first.x, first.P, t), t, None
            continue
        batch.add(t, z, sensor.R, sensor.model)
        if len(out["ess"]) < len(times) and t - t0 >= times[len(out["ess"])]:
            for name, stack in stacks.items():
                out[name].append(nees(stack.filter.x, stack.filter.P, x))
            # Gauss-Newton starts from the previous time's posterior mean, else the first filter's estimate
            guess = post.mean0 if out["ess"] else first.dynamics.propagate(first.x, t0 - t)
            x_map, P_map, _ = batch.solve(guess)
            out[LAPLACE].append(nees(x_map, P_map, x))
            post = adaptive_posterior(batch, guess, job["samples"], job["iterations"], sampler_rng)
            out[SAMPLED].append(nees(post.mean, post.covariance, x))
            out["ess"].append(post.ess)
            if len(out["ess"]) == len(times):
                break
    return out


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--runs", type=int, default=20, help="seeds 0..runs-1 (default 20)")
    p.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    p.add_argument("--times", default="2,5,10,20,40", help="s after the first scan (default 2,5,10,20,40)")
    p.add_argument("--filters", default="ekf,ukf", help="scenario filters to compare (default ekf,ukf)")
    p.add_argument("--samples", type=int, default=20_000, help="importance samples (default 20000)")
    p.add_argument("--iterations", type=int, default=6, help="adaptive sampling passes (default 6)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="scenario override, repeatable (e.g. sensors.radar.sigma_azimuth=4.35e-4)")
    p.add_argument("--json", type=Path, help="write the per-run NEES and the summary here")
    p.add_argument("--plot", type=Path, help="write a plot of mean NEES against time here (PNG)")
    args = p.parse_args(argv)
    try:
        args.times = sorted(float(v) for v in args.times.split(","))
    except ValueError:
        p.error(f"--times must be comma-separated seconds, got {args.times!r}")
    if args.runs < 2 or args.jobs < 1 or args.times[0] <= 0.0:
        p.error("need --runs >= 2, --jobs >= 1 and positive --times")
    args.filters = [f for f in args.filters.split(",") if f]
    return args


def summarise(results: list[dict], times: list[float]) -> dict:
    n = len(results)
    names = [k for k in results[0] if k != "ess"]
    return {"runs": n, "times_s": times, "band": (chi2.ppf([0.025, 0.975], 6 * n) / n).tolist(),
            "mean_nees": {k: np.mean([r[k] for r in results], axis=0).tolist() for k in names},
            "median_ess": np.median([r["ess"] for r in results], axis=0).tolist()}


def print_table(summary: dict, samples: int) -> None:
    lo, hi = summary["band"]
    names = list(summary["mean_nees"])
    print(f"mean NEES over {summary['runs']} runs (6 dof; 95 % band [{lo:.2f}, {hi:.2f}]); "
          f"* = inside the band")
    print(f"{'t [s]':>6} " + " ".join(f"{n:>26}" for n in names) + f" {'ESS of ' + str(samples):>16}")
    for i, t in enumerate(summary["times_s"]):
        cells = []
        for n in names:
            v = summary["mean_nees"][n][i]
            cells.append(f"{v:25.2f}{'*' if lo <= v <= hi else ' '}")
        print(f"{t:6.1f} " + " ".join(cells) + f" {summary['median_ess'][i]:16.0f}")


def plot(summary: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.axhspan(*summary["band"], color="0.85", label="95 % band")
    for name, values in summary["mean_nees"].items():
        ax.plot(summary["times_s"], values, marker="o", label=name)
    ax.set(xscale="log", yscale="log", xlabel="time after the first scan [s]", ylabel="mean NEES (6 dof)",
           title=f"leo_radar: NEES against the exact posterior ({summary['runs']} runs)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        cfg = load_scenario("leo_radar", args.overrides)
        for name in args.filters:
            build_filter_stack(cfg, name)
    except ScenarioError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    jobs = [{"seed": s, "times": args.times, "filters": args.filters, "overrides": args.overrides,
             "samples": args.samples, "iterations": args.iterations} for s in range(args.runs)]
    with ProcessPoolExecutor(args.jobs) as pool:
        results = list(tqdm(pool.map(one_run, jobs), total=args.runs, unit="run", desc="leo_radar posterior"))
    summary = summarise(results, args.times)
    print_table(summary, args.samples)
    if args.json:
        args.json.write_text(json.dumps({"summary": summary, "runs": results}, indent=1))
    if args.plot:
        plot(summary, args.plot)
        print(f"[posterior study] plot: {args.plot}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
