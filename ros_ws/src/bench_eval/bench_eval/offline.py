"""The offline-estimator stage between the bag and the metrics: estimators over a whole recorded run.

An offline estimator is registered in the entry-point group ``tracking_bench.offline`` as an
:class:`OfflineEstimator`; the scenario's ``scoring.offline`` section names the runs of it to score:

    scoring:
      offline:
        ss_rts: {estimator: rts, source: ss}     # RTS smoothing of filter "ss"'s recorded estimates
        newton: {estimator: newton, source: baseline, params: {order: 4, labels: [bx, by, bz, bvx, bvy, bvz]}}

``source`` is an estimator of the run (rts) or one of its measurements, a sensor or a derived measurement
(numerical differentiation: ``newton``, ``savgol``; dynamic orbit determination of a satellite pair from their
GNSS sensors ``source`` and ``params.second``: ``pair_orbit_fit``, orbit_sim.orbit_fit).

The scorer runs each over every bag and scores its output like another filter's (bench_eval.scoring).
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Callable

import numpy as np

from bench_engine.config import ScenarioError
from bench_eval.scoring import BagData, Estimates


@dataclass(frozen=True)
class OfflineEstimator:
    """``run(bag data, source estimator name, params) -> Estimates``; ``check(cfg, source, params)`` raises
    ScenarioError naming a bad value before any run starts."""

    run: Callable[[BagData, str, dict], Estimates]
    check: Callable[[dict, str, dict], None]


def _source_dynamics(cfg: dict, source: str):
    from bench_engine.graph import resolve_estimators
    from tracker_filters.builders import build_filter_stack
    if source not in (cfg.get("filters") or {}) and source not in resolve_estimators(cfg, None):
        raise ScenarioError(f"'scoring.offline': source '{source}' is not a filter of the scenario")
    return build_filter_stack(cfg, source).filter.dynamics


def _rts_check(cfg: dict, source: str, params: dict) -> None:
    if params:
        raise ScenarioError(f"'scoring.offline' rts takes no params, got {sorted(params)}")
    dynamics = _source_dynamics(cfg, source)
    if not hasattr(dynamics, "transition_matrix") or not hasattr(dynamics, "process_noise"):
        raise ScenarioError(f"'scoring.offline': the dynamics of '{source}' give no transition matrix")


def _rts_run(data: BagData, source: str, params: dict) -> Estimates:
    """Fixed-interval RTS smoothing (tracker_filters.smoothing) of ``source``'s estimates, with the source
    filter's own dynamics model between consecutive estimate times."""
    from tracker_filters.smoothing import smooth_estimates
    est = data.estimates[source]
    x, P = smooth_estimates(_source_dynamics(data.scenario, source), np.diff(est.t), est.x, est.P)
    return Estimates(est.steps, est.t, x, P, est.labels, {})


RTS = OfflineEstimator(run=_rts_run, check=_rts_check)


def _measurement_series(data: BagData, source: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(steps, t, z (K, d)) of a recorded measurement, in step order."""
    meas = data.measurements[source]
    steps = np.array(sorted(meas))
    return steps, np.array([data.truth[int(k)][0] for k in steps]), np.array([meas[int(k)] for k in steps])


def _differentiation_check(keys: dict[str, type | tuple[type, ...]]) -> Callable[[dict, str, dict], None]:
    def check(cfg: dict, source: str, params: dict) -> None:
        names = list((cfg.get("sensors") or {})) + list((cfg.get("derived_measurements") or {}))
        if source not in names:
            raise ScenarioError(f"'scoring.offline': source '{source}' is not a measurement of the scenario "
                                f"({names})")
        unknown, missing = set(params) - set(keys) - {"labels", "max_gap"}, set(keys) - set(params)
        if unknown or missing or not isinstance(params.get("labels"), list):
            raise ScenarioError(f"'scoring.offline' numerical differentiation of '{source}' takes params "
                                f"{sorted(keys)}, labels (positions then velocities) and optionally max_gap "
                                f"(s), got {sorted(params)}")
        gap = params.get("max_gap", 1.0)
        if isinstance(gap, bool) or not isinstance(gap, (int, float)) or not gap > 0:
            raise ScenarioError(f"'scoring.offline' params.max_gap must be a positive number of seconds, got {gap!r}")
        for key, kind in keys.items():
            if not isinstance(params[key], kind) or isinstance(params[key], bool) or params[key] < 1:
                raise ScenarioError(f"'scoring.offline' params.{key} must be a positive "
                                    f"{'integer' if kind is int else 'number'}, got {params[key]!r}")
    return check


def _differentiated(data: BagData, source: str, params: dict, derivative) -> Estimates:
    """Positions as measured with their numerical derivative; no covariance (NaN): these are not filters."""
    steps, t, z = _measurement_series(data, source)
    x = np.hstack([z, derivative(t, z)])
    if x.shape[1] != len(params["labels"]):
        raise ScenarioError(f"'scoring.offline': {len(params['labels'])} labels for {x.shape[1]} components "
                            f"(positions of '{source}' and their derivatives)")
    P = np.full((len(t), x.shape[1], x.shape[1]), np.nan)
    return Estimates(steps, t, x, P, list(params["labels"]), {})


def _newton_run(data: BagData, source: str, params: dict) -> Estimates:
    """Newton's divided-difference polynomial of degree ``order`` (paper 002's "Newton" method); windows never
    span a gap longer than ``max_gap`` seconds, and are one-sided at the ends of the day and of every gap."""
    from tracker_filters.differentiation import newton_derivative
    gap = float(params.get("max_gap", np.inf))
    return _differentiated(data, source, params, lambda t, z: newton_derivative(t, z, params["order"], gap))


def _savgol_run(data: BagData, source: str, params: dict) -> Estimates:
    """Savitzky-Golay: least-squares polynomial of ``polyorder`` over a window of ``window_s`` seconds (the
    largest odd number of samples it holds at the series' median spacing, at least polyorder + 2), so the
    window keeps its length in time whatever the sampling interval."""
    from tracker_filters.differentiation import savgol_derivative
    gap = float(params.get("max_gap", np.inf))

    def derivative(t: np.ndarray, z: np.ndarray) -> np.ndarray:
        spacing = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
        n = int(params["window_s"] / spacing) + 1
        window = max(n if n % 2 else n - 1, params["polyorder"] + 2 + params["polyorder"] % 2)
        return savgol_derivative(t, z, window, params["polyorder"], gap)
    return _differentiated(data, source, params, derivative)


NEWTON = OfflineEstimator(run=_newton_run, check=_differentiation_check({"order": int}))
SAVGOL = OfflineEstimator(run=_savgol_run, check=_differentiation_check({"window_s": (int, float), "polyorder": int}))


PAIR_FIT_KEYS = {"second", "zonal_degree", "drag", "ballistic_guess", "empirical_interval_s", "empirical_sigma"}


def _pair_fit_check(cfg: dict, source: str, params: dict) -> None:
    from orbit_sim.geopotential import ZONALS
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
    from orbit_sim.geopotential import ZONALS
    from orbit_sim.orbit_fit import ForceModel
    from orbit_sim.truth import build_earth
    earth = build_earth(cfg)
    degree = params.get("zonal_degree", 2)
    zonals = {n: (earth.j2 if n == 2 else ZONALS[n]) for n in range(2, degree + 1)}
    return ForceModel(earth.mu, earth.re, zonals, bool(params.get("drag", False)), earth.rotation_rate,
                      params.get("empirical_interval_s"))


def _fit_and_sample(t: np.ndarray, z: np.ndarray, sigma: float, model, ballistic_guess: float,
                    empirical_sigma: float | None, at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One satellite's orbit fitted to its fixes (orbit_sim.orbit_fit.fit_orbit): its states and covariance at
    the times ``at``."""
    from orbit_sim.orbit_fit import fit_orbit
    return fit_orbit(t, z, sigma, model, ballistic_guess, empirical_sigma).states(at)


def _both(jobs: list[tuple]) -> list[tuple[np.ndarray, np.ndarray]]:
    """``_fit_and_sample`` of the two satellites, one process each where this process may start children (the
    fits are independent and each takes a core for minutes with empirical accelerations); in turn otherwise."""
    import multiprocessing
    if multiprocessing.current_process().daemon or (os.cpu_count() or 1) < 2:
        return [_fit_and_sample(*job) for job in jobs]
    from concurrent.futures import ProcessPoolExecutor
    with ProcessPoolExecutor(len(jobs), mp_context=multiprocessing.get_context("spawn")) as pool:
        return list(pool.map(_fit_and_sample, *zip(*jobs)))


def _pair_fit_run(data: BagData, source: str, params: dict) -> Estimates:
    """Both satellites' orbits fitted to their own GNSS fixes by batch least squares (orbit_sim.orbit_fit), each
    fit's states and covariance at every truth step of the fixes' span; the state is the truth's 18 components
    (leader, follower, baseline = follower - leader, their covariance mapped linearly)."""
    from orbit_sim.pair import LABELS
    model = pair_force_model(data.scenario, params)
    all_steps = np.array(sorted(data.truth))
    all_t = np.array([data.truth[int(k)][0] for k in all_steps])
    names = (source, params["second"])
    fixes = [_measurement_series(data, name)[1:] for name in names]
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
