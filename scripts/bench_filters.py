#!/usr/bin/env python3
"""Per-step cost of the filters on the leo_radar problem, measured in-process (no ROS).

One step = ``Filter.process``: predict 0.1 s with the two-body + J2 RK4 model, then update with one radar
(range, azimuth, elevation) measurement. The truth is the CHAMP pass over the leo_radar station; each
filter starts at the truth with a converged-size covariance, so every step is an ordinary one.

    .venv/bin/python scripts/bench_filters.py                 # EKF, second-order EKF, UKF
    .venv/bin/python scripts/bench_filters.py --filters ekf ukf pf --steps 500
    .venv/bin/python scripts/bench_filters.py --sigma-accel 0 --param ekf2.relinearise=1.2 \
        --param ukf.relinearise=1.2                           # leo_radar's defaults (batch re-solves)

The median is the per-step budget's measure; the mean includes the batch re-solves of ``relinearise``
(amortised), the max their largest single step.

To bench another filter, register it in tracker_filters.registry; add a budget to TARGETS_US if it has one.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from bench_models.orbit_dynamics import OrbitJ2Dynamics
from bench_models.radar import GroundRadarModel
from orbit_sim.cowell import propagate
from orbit_sim.kepler import kepler_to_cartesian
from tracker_filters.registry import filter_names, make_filter

TARGETS_US = {"ekf": 100.0, "ukf": 300.0}
"""Median per-step budgets [us] (the product brief's targets)."""

CHAMP = (6739137.0, 0.00033, np.radians(87.2346), np.radians(303.3713), np.radians(81.5653), np.radians(80.0))
STATION = (np.radians(78.15306), np.radians(16.02889), 445.0)
THETA0 = np.radians(40.0)
PASS_START = 4330.0
"""s after the epoch: inside the ~420 s pass of CHAMP over the station (scenario leo_radar)."""
DT = 0.1
R = np.diag([1000.0, 0.017**2, 0.017**2])
SIGMA_ACCEL = 1.0
"""m/s^1.5 (default of --sigma-accel); the per-step cost does not depend on it. ``relinearise`` needs 0."""


def simulate(steps: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, GroundRadarModel]:
    """Truth states (steps + 1, 6), their times and noisy measurements (steps, 3) over the pass."""
    model = GroundRadarModel(*STATION, theta0=THETA0)
    x_epoch = kepler_to_cartesian(*CHAMP)
    x_start = propagate(x_epoch, np.array([0.0, PASS_START]))[-1]
    times = PASS_START + DT * np.arange(steps + 1)
    truth = propagate(x_start, times)
    rng = np.random.default_rng(seed)
    noise = rng.normal(size=(steps, 3)) * np.sqrt(np.diag(R))
    z = np.array([model.h(s, t) for s, t in zip(truth[1:], times[1:])]) + noise
    z[:, 1] = np.mod(z[:, 1], 2.0 * np.pi)
    return times, truth, z, model


def time_filter(
    name: str,
    params: dict,
    times: np.ndarray,
    truth: np.ndarray,
    z: np.ndarray,
    model: GroundRadarModel,
    sigma_accel: float = SIGMA_ACCEL,
) -> list[float]:
    """Wall-clock seconds of each ``process`` call of filter ``name`` along the simulated pass."""
    filt = make_filter(name, OrbitJ2Dynamics(sigma_accel), **params)
    filt.initialise(truth[0], np.diag([100.0**2] * 3 + [1.0] * 3), times[0])
    durations = []
    for t, zk in zip(times[1:], z):
        start = time.perf_counter()
        result = filt.process(t, zk, R, model)
        durations.append(time.perf_counter() - start)
        if not result.accepted:
            raise RuntimeError(f"{name}: measurement at t={t} rejected: {result.reason}")
    return durations


def parse_params(items: list[str]) -> dict[str, dict[str, float]]:
    """``ukf.alpha=0.5`` -> {"ukf": {"alpha": 0.5}}."""
    params: dict[str, dict[str, float]] = {}
    for item in items:
        key, _, value = item.partition("=")
        name, _, param = key.partition(".")
        if not (name and param and value):
            raise SystemExit(f"--param {item!r}: expected FILTER.NAME=VALUE, e.g. ukf.alpha=0.5")
        params.setdefault(name, {})[param] = float(value)
    return params


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--filters",
        nargs="+",
        default=["ekf", "ekf2", "ukf"],
        choices=filter_names(),
        help="filters to time (default: ekf ekf2 ukf)",
    )
    parser.add_argument("--steps", type=int, default=1000, help="measurement steps per repeat (default 1000)")
    parser.add_argument("--repeats", type=int, default=3, help="repeats; the table shows the best (default 3)")
    parser.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="FILTER.NAME=VALUE",
        help="filter parameter, e.g. --param ukf.alpha=0.5 (repeatable)",
    )
    parser.add_argument(
        "--sigma-accel",
        type=float,
        default=SIGMA_ACCEL,
        help=f"process noise [m/s^1.5] (default {SIGMA_ACCEL}; 0 for relinearise)",
    )
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    params = parse_params(args.param)
    times, truth, z, model = simulate(args.steps, args.seed)

    print(f"leo_radar, {args.steps} steps of predict {DT} s + radar update, best of {args.repeats} repeats")
    print(f"{'filter':<8}{'median us':>11}{'p90 us':>9}{'mean us':>9}{'max ms':>8}{'target us':>11}  status")
    for name in args.filters:
        runs = [
            time_filter(name, params.get(name, {}), times, truth, z, model, args.sigma_accel)
            for _ in range(args.repeats)
        ]
        median = min(statistics.median(r) for r in runs) * 1e6
        p90 = min(float(np.percentile(r, 90)) for r in runs) * 1e6
        mean = min(statistics.fmean(r) for r in runs) * 1e6
        worst = min(max(r) for r in runs) * 1e3
        target = TARGETS_US.get(name)
        status = "-" if target is None else ("ok" if median <= target else "OVER")
        target_text = "-" if target is None else f"{target:.0f}"
        print(f"{name:<8}{median:>11.1f}{p90:>9.1f}{mean:>9.1f}{worst:>8.1f}{target_text:>11}  {status}")


if __name__ == "__main__":
    main()
