"""The offline-estimator stage between the bag and the metrics: estimators over a whole recorded run.

An offline estimator is registered in the entry-point group ``tracking_bench.offline`` as an
:class:`OfflineEstimator`; the scenario's ``scoring.offline`` section names the runs of it to score:

    scoring:
      offline:
        ss_rts: {estimator: rts, source: ss}     # RTS smoothing of filter "ss"'s recorded estimates
        newton: {estimator: newton, source: baseline, params: {order: 4, labels: [bx, by, bz, bvx, bvy, bvz]}}

``source`` is an estimator of the run (rts) or one of its measurements, a sensor or a derived measurement
(numerical differentiation: ``newton``, ``savgol``). A study registers its own (e.g. an orbit fit to a sensor's
position fixes) in the same group.

The scorer runs each over every bag and scores its output like another filter's (bench_eval.scoring).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench_engine.config import ScenarioError
from bench_engine.graph import resolve_estimators
from bench_engine.settings import POSITIVE, NoKeys, Settings, at_least, setting
from bench_eval.scoring import BagData, Estimates
from tracker_filters.builders import build_filter_stack
from tracker_filters.differentiation import newton_derivative, savgol_derivative, savgol_window_length
from tracker_filters.smoothing import smooth_estimates


@dataclass(frozen=True)
class OfflineEstimator:
    """``run(bag data, source estimator name, params) -> Estimates``; ``check(cfg, source, params)`` raises
    ScenarioError naming a bad value before any run starts; ``params``: the Settings class of its parameters."""

    run: Callable[[BagData, str, Any], Estimates]
    check: Callable[[dict, str, Any], None]
    params: type = NoKeys


def _source_dynamics(cfg: dict, source: str):
    if source not in (cfg.get("filters") or {}) and source not in resolve_estimators(cfg, None):
        raise ScenarioError(f"'scoring.offline': source '{source}' is not a filter of the scenario")
    return build_filter_stack(cfg, source).filter.dynamics


def _rts_check(cfg: dict, source: str, params: NoKeys) -> None:
    dynamics = _source_dynamics(cfg, source)
    if not hasattr(dynamics, "transition_matrix") or not hasattr(dynamics, "process_noise"):
        raise ScenarioError(f"'scoring.offline': the dynamics of '{source}' give no transition matrix")


def _rts_run(data: BagData, source: str, params: NoKeys) -> Estimates:
    """Fixed-interval RTS smoothing (tracker_filters.smoothing) of ``source``'s estimates, with the source
    filter's own dynamics model between consecutive estimate times."""
    est = data.estimates[source]
    x, P = smooth_estimates(_source_dynamics(data.scenario, source), np.diff(est.t), est.x, est.P)
    return Estimates(est.steps, est.t, x, P, est.labels, {})


RTS = OfflineEstimator(run=_rts_run, check=_rts_check)


def measurement_series(data: BagData, source: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(steps, t, z (K, d)) of a recorded measurement, in step order."""
    meas = data.measurements[source]
    steps = np.array(sorted(meas))
    return steps, np.array([data.truth[int(k)][0] for k in steps]), np.array([meas[int(k)] for k in steps])


@dataclass(frozen=True, kw_only=True)
class Differentiation(Settings):
    """The parameters every numerical differentiation takes."""

    labels: list[str] = setting(doc="the labels of the result: the source's positions, then their velocities")
    max_gap: float = setting(float("inf"), unit="s", check=POSITIVE, doc="no window spans a longer gap")


@dataclass(frozen=True, kw_only=True)
class NewtonParameters(Differentiation):
    """``newton``: Newton's divided-difference polynomial."""

    order: int = setting(check=at_least(1), doc="the polynomial's degree")


@dataclass(frozen=True, kw_only=True)
class SavgolParameters(Differentiation):
    """``savgol``: Savitzky-Golay."""

    window_s: float = setting(unit="s", check=at_least(1, "a number"), doc="the window's length in time")
    polyorder: int = setting(check=at_least(1), doc="the least-squares polynomial's degree")


def _differentiation_check(cfg: dict, source: str, params: Differentiation) -> None:
    names = list(cfg.get("sensors") or {}) + list(cfg.get("derived_measurements") or {})
    if source not in names:
        raise ScenarioError(f"'scoring.offline': source '{source}' is not a measurement of the scenario ({names})")


def _differentiated(data: BagData, source: str, params: Differentiation, derivative) -> Estimates:
    """Positions as measured with their numerical derivative; no covariance (NaN): these are not filters."""
    steps, t, z = measurement_series(data, source)
    x = np.hstack([z, derivative(t, z)])
    if x.shape[1] != len(params.labels):
        raise ScenarioError(
            f"'scoring.offline': {len(params.labels)} labels for {x.shape[1]} components "
            f"(positions of '{source}' and their derivatives)"
        )
    P = np.full((len(t), x.shape[1], x.shape[1]), np.nan)
    return Estimates(steps, t, x, P, list(params.labels), {})


def _newton_run(data: BagData, source: str, params: NewtonParameters) -> Estimates:
    """Newton's divided-difference polynomial of degree ``order`` (paper 002's "Newton" method); windows never
    span a gap longer than ``max_gap`` seconds, and are one-sided at the ends of the day and of every gap."""
    return _differentiated(data, source, params, lambda t, z: newton_derivative(t, z, params.order, params.max_gap))


def _savgol_run(data: BagData, source: str, params: SavgolParameters) -> Estimates:
    """Savitzky-Golay: least-squares polynomial of ``polyorder`` over a window of ``window_s`` seconds (in samples
    at the series' median spacing: tracker_filters.differentiation.savgol_window_length), so the window keeps its
    length in time whatever the sampling interval."""

    def derivative(t: np.ndarray, z: np.ndarray) -> np.ndarray:
        spacing = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
        window = savgol_window_length(params.window_s, spacing, params.polyorder)
        return savgol_derivative(t, z, window, params.polyorder, params.max_gap)

    return _differentiated(data, source, params, derivative)


NEWTON = OfflineEstimator(run=_newton_run, check=_differentiation_check, params=NewtonParameters)
SAVGOL = OfflineEstimator(run=_savgol_run, check=_differentiation_check, params=SavgolParameters)
