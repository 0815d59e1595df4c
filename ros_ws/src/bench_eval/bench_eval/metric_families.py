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

from dataclasses import dataclass
from typing import Callable

import numpy as np

from bench_engine.config import Section
from bench_engine.labels import ORBIT
from bench_eval import metrics
from bench_eval.scoring import BagData

Tracks = dict[str, list[metrics.Track]]


@dataclass(frozen=True)
class Metric:
    """A metric family: ``options(section) -> dict``, ``score(tracks, runs, options) -> JSON-ready dict per
    filter``, ``series(tracks, runs, options) -> plot series per filter``, and optionally ``summary(one
    filter's scores) -> parts`` the scorer's one-line summary shows (bench_eval.scoring.print_summary) beside
    the generic ones."""

    options: Callable[[Section], dict]
    score: Callable[[Tracks, list[BagData], dict], dict]
    series: Callable[[Tracks, list[BagData], dict], dict]
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


def _error_options(sec: Section) -> dict:
    return {"skip_s": sec.non_negative("skip_s", 0.0),
            "position_threshold": sec.positive("position_threshold", 0.5),
            "velocity_threshold": sec.positive("velocity_threshold", 0.02),
            "hold_after_s": sec.get("hold_after_s", float, None, lambda v: v >= 0, ">= 0")}


CONVERGENCE = Metric(options=lambda sec: {},
                     score=lambda tracks, runs, options: metrics.score_convergence(tracks),
                     series=lambda tracks, runs, options: metrics.convergence_series(tracks))
ERRORS = Metric(options=_error_options, score=lambda tracks, runs, options: metrics.score_errors(tracks, **options),
                series=error_series)
