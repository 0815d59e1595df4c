"""The offline-estimator stage between the bag and the metrics: estimators over a whole recorded run.

An offline estimator is registered in the entry-point group ``tracking_bench.offline`` as an
:class:`OfflineEstimator`; the scenario's ``scoring.offline`` section names the runs of it to score:

    scoring:
      offline:
        ss_rts: {estimator: rts, source: ss}     # RTS smoothing of filter "ss"'s recorded estimates

The scorer runs each over every bag and scores its output like another filter's (bench_eval.scoring).
"""
from __future__ import annotations

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
    from bench_engine.graph import resolve_filters
    from tracker_filters.builders import build_filter_stack
    if source not in (cfg.get("filters") or {}) and source not in resolve_filters(cfg, None):
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
    from tracker_filters.smoothing import rts_smoother
    est = data.estimates[source]
    dynamics = _source_dynamics(data.scenario, source)
    dts = np.diff(est.t)
    Fs = np.array([dynamics.transition_matrix(x, dt) for x, dt in zip(est.x[:-1], dts)])
    Qs = np.array([dynamics.process_noise(x, dt) for x, dt in zip(est.x[:-1], dts)])
    x, P = rts_smoother(est.x, est.P, Fs, Qs)
    return Estimates(est.steps, est.t, x, P, est.labels, {})


RTS = OfflineEstimator(run=_rts_run, check=_rts_check)
