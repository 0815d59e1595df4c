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
from dataclasses import dataclass

import numpy as np

from bench_engine.config import ScenarioError
from bench_engine.settings import POSITIVE, Check, Settings, setting
from bench_eval.offline import OfflineEstimator, measurement_series
from bench_eval.scoring import BagData, Estimates, in_scoring_worker
from bench_studies.grace_velocity.pair_truth import LABELS
from orbit_sim.geopotential import ZONALS
from orbit_sim.orbit_fit import ForceModel, fit_orbit
from orbit_sim.truth import build_earth
from radar_sensor.sensor_types import read_sensors


@dataclass(frozen=True, kw_only=True)
class PairFitParameters(Settings):
    """``pair_orbit_fit``'s params: both satellites' orbits fitted to their GNSS fixes (orbit_sim.orbit_fit)."""

    second: str = setting(doc="the follower's GNSS sensor (source: the leader's)")
    zonal_degree: int = setting(
        2,
        check=Check(lambda v: v == 0 or 2 <= v <= max(ZONALS), f"0 (two-body) or 2..{max(ZONALS)}"),
        doc="zonal harmonics of the fit's gravity field",
    )
    drag: bool = setting(False, doc="model drag (and fit each satellite's C_d A / m)")
    ballistic_guess: float | None = setting(
        None, unit="m^2/kg", check=POSITIVE, doc="the fit's first guess of C_d A / m", default_text="0"
    )
    empirical_interval_s: float | None = setting(
        None,
        unit="s",
        check=POSITIVE,
        doc="reduced dynamics: empirical accelerations, piecewise constant over this interval (with empirical_sigma)",
    )
    empirical_sigma: float | None = setting(
        None, unit="m/s^2", check=POSITIVE, doc="their a-priori standard deviation (with empirical_interval_s)"
    )

    def validate(self, path: str) -> None:
        if (self.empirical_interval_s is None) != (self.empirical_sigma is None):
            raise ScenarioError(f"'{path}.empirical_interval_s' and empirical_sigma go together")


def _position_sensors(cfg: dict) -> dict[str, float]:
    """The scenario's sensors that fix a position: name -> sigma_position."""
    return {name: s.model.sigma_position for name, s in read_sensors(cfg).items() if hasattr(s.model, "sigma_position")}


def _pair_fit_check(cfg: dict, source: str, params: PairFitParameters) -> None:
    sensors = _position_sensors(cfg)
    for name in (source, params.second):
        if name not in sensors:
            raise ScenarioError(
                f"'scoring.offline' pair_orbit_fit: '{name}' is not a position sensor of the scenario "
                "(source and params.second: the leader's and the follower's GNSS)"
            )


def pair_force_model(cfg: dict, params: PairFitParameters):
    """The fit's orbit_sim.orbit_fit.ForceModel from the scenario's earth and the params (zonal_degree, drag,
    empirical_interval_s)."""
    earth = build_earth(cfg)
    zonals = {n: (earth.j2 if n == 2 else ZONALS[n]) for n in range(2, params.zonal_degree + 1)}
    return ForceModel(earth.mu, earth.re, zonals, params.drag, earth.rotation_rate, params.empirical_interval_s)


def _fit_and_sample(
    t: np.ndarray,
    z: np.ndarray,
    sigma: float,
    model,
    ballistic_guess: float,
    empirical_sigma: float | None,
    at: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """One satellite's orbit fitted to its fixes (orbit_sim.orbit_fit.fit_orbit): its states and covariance at
    the times ``at``."""
    return fit_orbit(t, z, sigma, model, ballistic_guess, empirical_sigma).states(at)


def _both(jobs: list[tuple]) -> list[tuple[np.ndarray, np.ndarray]]:
    """``_fit_and_sample`` of the two satellites, one process each where this process may start children and
    run on two CPUs (the fits are independent and each takes a core for seconds, tens of seconds with empirical
    accelerations); in turn otherwise, e.g. in the scorer's worker processes, which score bags in parallel
    (bench_eval.scoring.in_scoring_worker)."""
    if in_scoring_worker() or multiprocessing.current_process().daemon or len(os.sched_getaffinity(0)) < 2:
        return [_fit_and_sample(*job) for job in jobs]
    with ProcessPoolExecutor(len(jobs), mp_context=multiprocessing.get_context("spawn")) as pool:
        return list(pool.map(_fit_and_sample, *zip(*jobs)))


def _pair_fit_run(data: BagData, source: str, params: PairFitParameters) -> Estimates:
    """Both satellites' orbits fitted to their own GNSS fixes by batch least squares (orbit_sim.orbit_fit), each
    fit's states and covariance at every truth step of the fixes' span; the state is the truth's 18 components
    (leader, follower, baseline = follower - leader, their covariance mapped linearly)."""
    model = pair_force_model(data.scenario, params)
    all_steps = np.array(sorted(data.truth))
    all_t = np.array([data.truth[int(k)][0] for k in all_steps])
    names = (source, params.second)
    fixes = [measurement_series(data, name)[1:] for name in names]
    keep = (all_t >= max(t[0] for t, _ in fixes)) & (all_t <= min(t[-1] for t, _ in fixes))  # the fits' spans
    sigma = _position_sensors(data.scenario)
    (x1, P1), (x2, P2) = _both(
        [
            (t, z, sigma[name], model, params.ballistic_guess or 0.0, params.empirical_sigma, all_t[keep])
            for name, (t, z) in zip(names, fixes)
        ]
    )
    L = np.zeros((18, 12))  # [leader, follower, follower - leader] from [leader, follower]
    L[:12] = np.eye(12)
    L[12:, :6], L[12:, 6:] = -np.eye(6), np.eye(6)
    P = np.zeros((len(x1), 12, 12))
    P[:, :6, :6], P[:, 6:, 6:] = P1, P2
    return Estimates(all_steps[keep], all_t[keep], np.hstack([x1, x2]) @ L.T, L @ P @ L.T, list(LABELS), {})


PAIR_ORBIT_FIT = OfflineEstimator(run=_pair_fit_run, check=_pair_fit_check, params=PairFitParameters)
