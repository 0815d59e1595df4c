"""grace_velocity's offline estimator ``pair_orbit_fit`` (registered in tracking_bench.offline): dynamic orbit
determination of the satellite pair, each satellite's orbit fitted to its own GNSS fixes by batch least squares
(the generic fit: orbit_sim.orbit_fit), sampled at every truth step of the fixes' span as the pair truth's 18
components (bench_studies.grace_velocity.pair_truth).

    scoring:
      offline:
        orbit_fit: {estimator: pair_orbit_fit, source: gnss1, params: {second: gnss2, zonal_degree: 6, drag: true}}
"""
from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from bench_engine.config import ScenarioError
from bench_eval.offline import OfflineEstimator, measurement_series
from bench_eval.scoring import BagData, Estimates
from bench_studies.grace_velocity.pair_truth import LABELS
from orbit_sim.geopotential import ZONALS
from orbit_sim.orbit_fit import ForceModel, fit_orbit
from orbit_sim.truth import build_earth

PAIR_FIT_KEYS = {"second", "zonal_degree", "drag", "ballistic_guess", "empirical_interval_s", "empirical_sigma"}


def _pair_fit_check(cfg: dict, source: str, params: dict) -> None:
    sensors = cfg.get("sensors") or {}
    for name in (source, params.get("second")):
        if not isinstance(sensors.get(name), dict) or "sigma_position" not in sensors[name]:
            raise ScenarioError(f"'scoring.offline' pair_orbit_fit: '{name}' is not a position sensor of the scenario "
                                "(source and params.second: the leader's and the follower's GNSS)")
    unknown = set(params) - PAIR_FIT_KEYS
    if unknown or "second" not in params:
        raise ScenarioError(f"'scoring.offline' pair_orbit_fit takes params {sorted(PAIR_FIT_KEYS)} (second "
                            f"required), got {sorted(params)}")
    degree = params.get("zonal_degree", 2)
    if not isinstance(degree, int) or isinstance(degree, bool) or not 0 <= degree <= max(ZONALS) or degree == 1:
        raise ScenarioError(f"'scoring.offline' params.zonal_degree must be 0 (two-body) or 2..{max(ZONALS)}, "
                            f"got {degree!r}")
    if not isinstance(params.get("drag", False), bool):
        raise ScenarioError(f"'scoring.offline' params.drag must be true or false, got {params['drag']!r}")
    for key in ("ballistic_guess", "empirical_interval_s", "empirical_sigma"):
        value = params.get(key)
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float)) or value <= 0):
            raise ScenarioError(f"'scoring.offline' params.{key} must be a positive number, got {value!r}")
    if ("empirical_interval_s" in params) != ("empirical_sigma" in params):
        raise ScenarioError("'scoring.offline' params.empirical_interval_s and empirical_sigma go together")


def pair_force_model(cfg: dict, params: dict):
    """The fit's orbit_sim.orbit_fit.ForceModel from the scenario's earth and the params (zonal_degree, drag,
    empirical_interval_s)."""
    earth = build_earth(cfg)
    degree = params.get("zonal_degree", 2)
    zonals = {n: (earth.j2 if n == 2 else ZONALS[n]) for n in range(2, degree + 1)}
    return ForceModel(earth.mu, earth.re, zonals, bool(params.get("drag", False)), earth.rotation_rate,
                      params.get("empirical_interval_s"))


def _fit_and_sample(t: np.ndarray, z: np.ndarray, sigma: float, model, ballistic_guess: float,
                    empirical_sigma: float | None, at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One satellite's orbit fitted to its fixes (orbit_sim.orbit_fit.fit_orbit): its states and covariance at
    the times ``at``."""
    return fit_orbit(t, z, sigma, model, ballistic_guess, empirical_sigma).states(at)


def _both(jobs: list[tuple]) -> list[tuple[np.ndarray, np.ndarray]]:
    """``_fit_and_sample`` of the two satellites, one process each where this process may start children (the
    fits are independent and each takes a core for minutes with empirical accelerations); in turn otherwise."""
    if multiprocessing.current_process().daemon or (os.cpu_count() or 1) < 2:
        return [_fit_and_sample(*job) for job in jobs]
    with ProcessPoolExecutor(len(jobs), mp_context=multiprocessing.get_context("spawn")) as pool:
        return list(pool.map(_fit_and_sample, *zip(*jobs)))


def _pair_fit_run(data: BagData, source: str, params: dict) -> Estimates:
    """Both satellites' orbits fitted to their own GNSS fixes by batch least squares (orbit_sim.orbit_fit), each
    fit's states and covariance at every truth step of the fixes' span; the state is the truth's 18 components
    (leader, follower, baseline = follower - leader, their covariance mapped linearly)."""
    model = pair_force_model(data.scenario, params)
    all_steps = np.array(sorted(data.truth))
    all_t = np.array([data.truth[int(k)][0] for k in all_steps])
    names = (source, params["second"])
    fixes = [measurement_series(data, name)[1:] for name in names]
    keep = (all_t >= max(t[0] for t, _ in fixes)) & (all_t <= min(t[-1] for t, _ in fixes))  # the fits' spans
    (x1, P1), (x2, P2) = _both([(t, z, float(data.scenario["sensors"][name]["sigma_position"]), model,
                                 params.get("ballistic_guess", 0.0), params.get("empirical_sigma"), all_t[keep])
                                for name, (t, z) in zip(names, fixes)])
    L = np.zeros((18, 12))  # [leader, follower, follower - leader] from [leader, follower]
    L[:12] = np.eye(12)
    L[12:, :6], L[12:, 6:] = -np.eye(6), np.eye(6)
    P = np.zeros((len(x1), 12, 12))
    P[:, :6, :6], P[:, 6:, 6:] = P1, P2
    return Estimates(all_steps[keep], all_t[keep], np.hstack([x1, x2]) @ L.T, L @ P @ L.T, list(LABELS), {})


PAIR_ORBIT_FIT = OfflineEstimator(run=_pair_fit_run, check=_pair_fit_check)
