"""How consistent can any estimator be early in the leo_radar pass? The filters against the exact posterior.

With 1 deg angles the first scans leave a posterior that is far from Gaussian (curved range shell, ring of
cross-range speeds). The study measures, on identical measurements per seed and at chosen times after the
first scan, the NEES (6 dof; mean over runs, with the runs' 95 % chi-square band) of:
  the scenario's filters (default: its ``ekf`` and ``ukf``), run by the graph's cores in process
  (bench_engine.inprocess);
  the batch MAP with its Laplace covariance (Gauss-Newton over every scan; relinearisation.PassBatch);
  the exact posterior's mean and covariance, by adaptive importance sampling
  (tracker_filters/posterior_sampling.py) - the reference any consistent estimator must match.
A Gaussian filter can only be consistent where the Laplace approximation is; where only the sampled
posterior is, consistency needs a sample-based estimator.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from scipy.stats import chi2

from bench_engine.config import load_scenario
from bench_engine.inprocess import run_in_process
from bench_eval.report import Plot, save_plot
from radar_sensor.sensor import build_sensor
from tracker_filters.builders import build_filter_stack
from tracker_filters.posterior_sampling import adaptive_posterior
from tracker_filters.relinearisation import PassBatch

LAPLACE, SAMPLED = "batch MAP (Laplace)", "exact posterior (sampled)"


def nees(x: np.ndarray, P: np.ndarray, truth: np.ndarray) -> float:
    e = x - truth
    return float(e @ np.linalg.solve(P, e))


def one_run(job: dict) -> dict:
    """NEES of every estimator at each requested time for one seed (module docstring)."""
    times = job["times"]
    cfg = load_scenario("leo_radar", job["overrides"] + [f"time.duration={max(times) + 1.0}"])
    run = run_in_process(cfg, job["estimators"], seed=job["seed"])
    sensor, dynamics = build_sensor(cfg, "radar"), build_filter_stack(cfg, job["estimators"][0]).filter.dynamics
    truth = {s.step: s.state for s in run.items["/truth/state"]}
    estimates = {name: {e.step: e for e in run.items[f"/{name}/estimate"]} for name in job["estimators"]}
    sampler_rng = np.random.default_rng([job["seed"], 1])
    out = {name: [] for name in [*job["estimators"], LAPLACE, SAMPLED]}
    out["ess"], post = [], None
    first, *scans = run.items["/radar/measurement"]
    prior = estimates[job["estimators"][0]][first.step]
    batch = PassBatch(dynamics, prior.x, prior.P, first.t)
    for m in scans:
        batch.add(m.t, m.z, m.R, sensor.model)
        if m.t - first.t < times[len(out["ess"])]:
            continue
        x = truth[m.step]
        for name in job["estimators"]:
            est = estimates[name][m.step]
            out[name].append(nees(est.x, est.P, x))
        # Gauss-Newton starts from the previous time's posterior mean, else the first filter's prior
        guess = post.mean0 if post is not None else prior.x
        x_map, P_map, _ = batch.solve(guess)
        out[LAPLACE].append(nees(x_map, P_map, x))
        post = adaptive_posterior(batch, guess, job["samples"], job["iterations"], sampler_rng)
        out[SAMPLED].append(nees(post.mean, post.covariance, x))
        out["ess"].append(post.ess)
        if len(out["ess"]) == len(times):
            break
    return out


def summarise(results: list[dict], times: list[float]) -> dict:
    n = len(results)
    names = [k for k in results[0] if k != "ess"]
    return {
        "runs": n,
        "times_s": times,
        "band": (chi2.ppf([0.025, 0.975], 6 * n) / n).tolist(),
        "mean_nees": {k: np.mean([r[k] for r in results], axis=0).tolist() for k in names},
        "median_ess": np.median([r["ess"] for r in results], axis=0).tolist(),
    }


def print_table(summary: dict, samples: int) -> None:
    lo, hi = summary["band"]
    names = list(summary["mean_nees"])
    print(f"mean NEES over {summary['runs']} runs (6 dof; 95 % band [{lo:.2f}, {hi:.2f}]); * = inside the band")
    print(f"{'t [s]':>6} " + " ".join(f"{n:>26}" for n in names) + f" {'ESS of ' + str(samples):>16}")
    for i, t in enumerate(summary["times_s"]):
        cells = []
        for n in names:
            v = summary["mean_nees"][n][i]
            cells.append(f"{v:25.2f}{'*' if lo <= v <= hi else ' '}")
        print(f"{t:6.1f} " + " ".join(cells) + f" {summary['median_ess'][i]:16.0f}")


def plot(summary: dict, path: Path) -> Path:
    """Mean NEES of every estimator against time, with the runs' 95 % band (PNG at ``path``)."""

    def draw(fig: Figure) -> None:
        ax = fig.subplots()
        ax.axhspan(*summary["band"], color="0.85", label="95 % band")
        for name, values in summary["mean_nees"].items():
            ax.plot(summary["times_s"], values, marker="o", label=name)
        ax.set(
            xscale="log",
            yscale="log",
            xlabel="time after the first scan [s]",
            ylabel="mean NEES (6 dof)",
            title=f"leo_radar: NEES against the exact posterior ({summary['runs']} runs)",
        )
        ax.legend(fontsize=8)

    return save_plot(path.parent, Plot(path.name, "", draw, (7.0, 4.0)))
