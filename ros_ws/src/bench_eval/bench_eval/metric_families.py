"""The registered metric families (entry-point group ``tracking_bench.metrics``) a scenario's ``scoring.metric``
names. A family reads its options from the ``scoring`` section, scores the tracks of every run, and gives the
time series its plots need.

- ``convergence``: RMSE over runs summarised by peak, convergence time, band and converged level, per axis;
  NEES. (A study extends a family with its own scores by registering another Metric built on it.)
- ``errors``: mean absolute error per component (per run too), settling time under per-axis thresholds,
  fraction inside +-3 sigma, NEES; options ``skip_s``, ``position_threshold`` [m], ``velocity_threshold`` [m/s]
  and ``hold_after_s`` (per run: do the thresholds hold from then on).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench_engine.labels import ORBIT
from bench_engine.settings import NON_NEGATIVE, POSITIVE, NoKeys, Settings, setting
from bench_eval import metrics
from bench_eval.scoring import BagData

Tracks = dict[str, list[metrics.Track]]


@dataclass(frozen=True)
class Metric:
    """A metric family: ``options``, the Settings class of its keys in the ``scoring`` section (beside
    ``metric``, ``offline`` and ``bounds``); ``score(tracks, runs, options) -> JSON-ready dict per estimator``;
    ``series(tracks, runs, options) -> plot series per estimator``; and optionally ``summary(one estimator's
    scores) -> parts`` the scorer's one-line summary shows (bench_eval.summary.print_summary) beside the generic
    ones."""

    options: type
    score: Callable[[Tracks, list[BagData], Any], dict]
    series: Callable[[Tracks, list[BagData], Any], dict]
    summary: Callable[[dict], list[str]] | None = None


def error_series(tracks: Tracks, runs: list[BagData] | None = None, options: dict | None = None) -> dict:
    """Per filter: t (s from the first stamp), RMS error over runs and mean 1-sigma per position and velocity
    component."""
    t0 = min(float(tr.t[0]) for group in tracks.values() for tr in group)
    series = {}
    for name, group in tracks.items():
        comps = [c for c in group[0].error_labels if c in ORBIT]
        t, _ = metrics.rmse_over_runs(group, comps[:1])
        rmse, sigma = {}, {}
        for c in comps:
            i = group[0].error_labels.index(c)
            rmse[c] = metrics.rmse_over_runs(group, [c])[1]
            sigma[c] = np.nanmean(metrics.on_grid(group, [np.sqrt(tr.P[:, i, i]) for tr in group])[1], axis=0)
        series[name] = {"t": t - t0, "rmse": rmse, "sigma": sigma}
    return series


@dataclass(frozen=True, kw_only=True)
class ErrorOptions(Settings):
    """The ``errors`` family's keys of the ``scoring`` section."""

    skip_s: float = setting(0.0, unit="s", check=NON_NEGATIVE, doc="the start of each run not scored")
    position_threshold: float = setting(
        0.5, unit="m", check=POSITIVE, doc="settled: every position error component below it"
    )
    velocity_threshold: float = setting(
        0.02, unit="m/s", check=POSITIVE, doc="settled: every velocity error component below it"
    )
    hold_after_s: float | None = setting(
        None, unit="s", check=NON_NEGATIVE, doc="per run: do the thresholds hold from then on (null: not scored)"
    )


def _score_errors(tracks: Tracks, runs: list[BagData], o: ErrorOptions) -> dict:
    return metrics.score_errors(
        tracks,
        skip_s=o.skip_s,
        position_threshold=o.position_threshold,
        velocity_threshold=o.velocity_threshold,
        hold_after_s=o.hold_after_s,
    )


CONVERGENCE = Metric(
    options=NoKeys,
    score=lambda tracks, runs, options: metrics.score_convergence(tracks),
    series=lambda tracks, runs, options: metrics.convergence_series(tracks),
)
ERRORS = Metric(options=ErrorOptions, score=_score_errors, series=error_series)
