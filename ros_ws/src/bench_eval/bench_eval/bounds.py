"""Lower bounds on the estimation error of a recorded run, and every estimator's efficiency against them.

A bound is computed from the truth trajectory and the measurement models of a run (the scans its sensors
delivered, the scenario's models and noise), independently of the estimators. It is registered in the
entry-point group ``tracking_bench.bounds`` as a :class:`Bound` and configured in the scenario's ``scoring``
section:

    scoring:
      bounds:
        pcrb:                       # the name it is reported under
          bound: pcrb               # a registered Bound
          params: {dynamics: truth, prior: ukf}  # or dynamics: {model: orbit_j2, sigma_accel: 0.0}
          from_s: 100.0             # optional: summaries over the steps from this time (s since the first
                                    # estimate of the run), default 0

``Bound.run(bag data, params) -> BoundSeries``: per step (the truth's step index and time) a bound covariance
over named state components (``labels``, the truth's labels: x y z vx vy vz, ...), NaN where the bound is not
finite yet. ``Bound.check(cfg, params)`` raises ScenarioError for a bad value before any run.

The scorer (bench_eval.scoring.score_bags) adds to every scored estimator's score block
``bounds: {NAME: {position: {rmse, sqrt_bound, efficiency, final_rmse, final_sqrt_bound}, velocity: {...},
axes: {label: {...}}}}`` and to its plot series ``bounds: {NAME: {t, position, velocity, axes}}`` (√bound per
step on the series' time axis, for a dashed curve). Definitions (:func:`score_bound`): per step,
RMSE_k = sqrt(mean over runs of |e_k|^2) over a group's components and √bound_k = sqrt(mean over runs of
trace(P_bound,k)) (the bound of the run-averaged MSE). Over the steps from ``from_s``: ``rmse`` and
``sqrt_bound`` are the RMS over time of each (in the group's unit), ``efficiency`` is
(mean over steps of RMSE_k^2 / bound_k)^(-1/2), every step weighted alike whatever its error level (an RMS
over time would be the first steps', where a prior of metres meets errors of centimetres later), 1 = efficient
(a lower bound: <= 1 up to Monte Carlo error); ``final_*`` are the values at the last step.

Registered bounds: ``pcrb`` (posterior CRB along the truth: tracker_filters.pcrb) here; others where their
models are (e.g. ``wahba``, a star camera's per-frame attitude bound: bench_studies.star_tracker.bounds).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench_engine import plugins
from bench_engine.config import ScenarioError
from bench_engine.graph import resolve_estimators
from bench_engine.labels import POSITION, VELOCITY
from bench_engine.scenario import default_estimators
from bench_engine.settings import NON_NEGATIVE, NoKeys, Settings, setting, variant
from bench_eval import metrics
from bench_eval.bag_data import BagData
from bench_models.truth_dynamics import truth_dynamics
from tracker_filters.builders import build_dynamics, build_filter_stack, measurement_source
from tracker_filters.filter_settings import DynamicsSettings
from tracker_filters.pcrb import pcrb_along_truth

GROUPS = {"position": POSITION, "velocity": VELOCITY}


@dataclass
class BoundSeries:
    """A bound over one run: covariance ``P`` (K, n, n) over ``labels`` at the truth steps ``steps`` (K,),
    times ``t`` (K,) [s]. ``labels`` name error components as the estimators' do (bench_models.states
    .error_labels: a state label, or rx ry rz for a quaternion block); an estimator is scored on those it has."""

    steps: np.ndarray
    t: np.ndarray
    labels: list[str]
    P: np.ndarray


@dataclass(frozen=True)
class Bound:
    """``run(bag data, params) -> BoundSeries``; ``check(cfg, params)`` raises ScenarioError naming a bad
    value before any run starts; ``params``: the Settings class of its parameters."""

    run: Callable[[BagData, Any], BoundSeries]
    check: Callable[[dict, Any], None]
    params: type = NoKeys


@dataclass(frozen=True, kw_only=True)
class BoundRun(Settings):
    """One entry of ``scoring.bounds``: the registered ``bound``, its ``params``, the summaries' start."""

    bound: str = setting(
        doc="a registered bound (entry-point group tracking_bench.bounds)", choices=lambda: plugins.names("bounds")
    )
    params: Settings = variant(
        "bound",
        lambda: plugins.names("bounds"),
        lambda name: plugins.load("bounds", name).params,
        inline=False,
        doc="the bound's parameters",
    )
    from_s: float = setting(
        0.0, unit="s", check=NON_NEGATIVE, doc="the summaries (efficiency) start this long after the first truth sample"
    )


def _bound_at(series: BoundSeries, t: np.ndarray, labels: list[str], tol: float = metrics.DEFAULT_TOL_S) -> np.ndarray:
    """The bound covariance over ``labels`` at the times ``t`` (NaN where the bound has no step there)."""
    idx = [series.labels.index(lab) for lab in labels]
    i = np.clip(np.searchsorted(series.t, t - tol), 0, len(series.t) - 1)
    out = series.P[i][:, idx][:, :, idx]
    out[np.abs(series.t[i] - t) > tol] = np.nan
    return out


def _summary(rmse: np.ndarray, root_bound: np.ndarray, keep: np.ndarray) -> dict:
    ok = keep & np.isfinite(rmse) & np.isfinite(root_bound)
    if not ok.any():
        return {"rmse": None, "sqrt_bound": None, "efficiency": None, "final_rmse": None, "final_sqrt_bound": None}
    r, b = float(np.sqrt(np.mean(rmse[ok] ** 2))), float(np.sqrt(np.mean(root_bound[ok] ** 2)))
    ratio = float(np.mean((rmse[ok] / root_bound[ok]) ** 2))
    last = np.flatnonzero(ok)[-1]
    return {
        "rmse": r,
        "sqrt_bound": b,
        "efficiency": 1.0 / np.sqrt(ratio) if ratio > 0 else None,
        "final_rmse": float(rmse[last]),
        "final_sqrt_bound": float(root_bound[last]),
    }


def score_bound(tracks: list[metrics.Track], bounds: list[BoundSeries], from_s: float, t0: float) -> tuple[dict, dict]:
    """(scores, series) of one estimator's tracks (one per run) against the same runs' bounds (module
    docstring); ``t0`` is the plot series' time origin."""
    labels = [lab for lab in tracks[0].error_labels if lab in bounds[0].labels]
    P = [_bound_at(b, tr.t, labels) for tr, b in zip(tracks, bounds)]
    grid, P_grid = metrics.on_grid(tracks, P)
    keep = np.zeros(len(grid), bool)
    for tr in tracks:  # the steps from from_s after each run's first estimate
        keep[np.searchsorted(grid, tr.t[tr.t - tr.t[0] >= from_s] - metrics.DEFAULT_TOL_S)] = True
    scores, series = {}, {"t": grid - t0}
    comps = {g: [c for c in members if c in labels] for g, members in GROUPS.items()}
    for group, members in [*comps.items(), *((c, [c]) for c in labels)]:
        if not members:
            continue
        i = [labels.index(c) for c in members]
        rmse = metrics.rmse_over_runs(tracks, members)[1]
        trace = np.trace(P_grid[:, :, i][:, :, :, i], axis1=2, axis2=3)  # (runs, steps), NaN: no bound
        count = np.sum(np.isfinite(trace), axis=0)
        root = np.sqrt(np.where(count > 0, np.nansum(trace, axis=0) / np.maximum(count, 1), np.nan))
        target_scores, target_series = (
            (scores, series) if group in GROUPS else (scores.setdefault("axes", {}), series.setdefault("axes", {}))
        )
        target_scores[group] = _summary(rmse, root, keep)
        target_series[group] = root
    return scores, series


def compute_bounds(runs: list[BagData], bounds: Mapping[str, BoundRun]) -> None:
    """Compute each configured bound over each run once, into the run's ``bounds`` (name -> BoundSeries), where
    metric families may use it too (e.g. a bound in a sensor's coordinates)."""
    for data in runs:
        for name, b in bounds.items():
            if name not in data.bounds:
                data.bounds[name] = plugins.load("bounds", b.bound).run(data, b.params)


def score_bounds(
    tracks: Mapping[str, list[metrics.Track]], runs: list[BagData], bounds: Mapping[str, BoundRun]
) -> tuple[dict, dict]:
    """({estimator: {bound: scores}}, {estimator: {bound: series}}) for every scored estimator whose tracks
    share components with the bound (module docstring), from the runs' bounds (:func:`compute_bounds`)."""
    if not bounds or not tracks:
        return {}, {}
    compute_bounds(runs, bounds)
    t0 = min(float(tr.t[0]) for group in tracks.values() for tr in group)
    per_run = {name: [d.bounds[name] for d in runs] for name in bounds}
    scores: dict = {}
    series: dict = {}
    for est, group in tracks.items():
        having = [i for i, d in enumerate(runs) if est in d.estimates]
        if len(having) != len(group):
            continue
        for name, b in bounds.items():
            own = [per_run[name][i] for i in having]
            if not set(group[0].error_labels) & set(own[0].labels):
                continue
            s, ser = score_bound(group, own, b.from_s, t0)
            scores.setdefault(est, {})[name] = s
            series.setdefault(est, {})[name] = ser
    return scores, series


# --- pcrb: the posterior Cramér-Rao bound along the truth (tracker_filters.pcrb) -----------------------------


@dataclass(frozen=True, kw_only=True)
class PcrbParameters(Settings):
    """The pcrb bound's ``params``."""

    dynamics: str | DynamicsSettings = setting(
        doc="truth: the truth model's own deterministic dynamics (bench_models.truth_dynamics); or a dynamics "
        "section as a filter's (a registered model and its process noise)"
    )
    prior: str | None = setting(
        None, doc="the filter whose initialiser gives J_0", default_text="the first of the scenario's estimators"
    )
    sensors: list[str] | None = setting(
        None, doc="the measurements whose information it adds", default_text="the prior filter's"
    )

    def validate(self, path: str) -> None:
        if isinstance(self.dynamics, str) and self.dynamics != "truth":
            raise ScenarioError(f"'{path}.dynamics' must be truth or a dynamics section, got {self.dynamics!r}")


def _pcrb_settings(cfg: dict, params: PcrbParameters):
    """(dynamics, prior filter, sensors) of the pcrb params (:class:`PcrbParameters`)."""
    if params.dynamics == "truth":
        dynamics = truth_dynamics(cfg)
    else:
        dynamics = build_dynamics(params.dynamics, cfg)
    defaults = default_estimators(cfg) or []
    prior = params.prior or (defaults[0] if defaults else None)
    if prior is None:
        raise ScenarioError(f"missing key '{params.where('prior')}' (the scenario selects no estimators)")
    if prior not in (cfg.get("filters") or {}) and prior not in resolve_estimators(cfg, None):
        raise ScenarioError(f"'{params.where('prior')}': '{prior}' is not a filter of the scenario")
    sensors = params.sensors or list(build_filter_stack(cfg, prior).sensors)
    return dynamics, prior, sensors


def _pcrb_check(cfg: dict, params: PcrbParameters) -> None:
    dynamics, _, sensors = _pcrb_settings(cfg, params)
    for name in sensors:
        measurement_source(cfg, name, dynamics.labels)


def _pcrb_run(data: BagData, params: PcrbParameters) -> BoundSeries:
    """The PCRB (tracker_filters.pcrb) of the run: the truth at the steps where the bound's sensors delivered a
    scan, F and Q of ``dynamics`` between them, each scan's information H^T R^{-1} H with the sensor's own model
    and R. J_0 is the inverse of the prior filter's initial covariance, from its initialiser applied to the
    noise-free first scan (h of the truth): what the filters know at their first estimate (for ``first_scan``
    that scan's information is in it; a ``given`` prior does not use it), so the first scan adds nothing
    more. State components are the dynamics model's labels, taken from the truth by label."""
    cfg = data.scenario
    dynamics, prior, names = _pcrb_settings(cfg, params)
    labels = list(dynamics.labels)
    missing = [lab for lab in labels if lab not in data.truth_labels]
    if missing:
        raise ScenarioError(f"'scoring.bounds': the bound's dynamics state has components the truth lacks: {missing}")
    sources = {n: measurement_source(cfg, n, labels) for n in names}
    steps = np.array(sorted(set().union(*(data.measurements.get(n, {}) for n in names))), dtype=np.int64)
    if not len(steps):
        return BoundSeries(steps, np.zeros(0), labels, np.zeros((0, len(labels), len(labels))))
    index = [data.truth_labels.index(lab) for lab in labels]
    t = np.array([data.truth[int(k)][0] for k in steps])
    x = np.array([data.truth[int(k)][1][index] for k in steps])
    scans = [[(sources[n].model, sources[n].R) for n in names if int(k) in data.measurements.get(n, {})] for k in steps]
    first = next(n for n in names if int(steps[0]) in data.measurements.get(n, {}))
    stack = build_filter_stack(cfg, prior)
    model = sources[first].model
    _, P0 = stack.initialise(model.h(x[0], t[0]), sources[first].R, sources[first], t[0])
    prior_labels = list(stack.filter.dynamics.labels)
    keep = [prior_labels.index(lab) for lab in labels]
    J0 = np.linalg.inv(np.asarray(P0, float)[np.ix_(keep, keep)])
    return BoundSeries(steps, t, labels, pcrb_along_truth(dynamics, t, x, scans, J0))


PCRB = Bound(run=_pcrb_run, check=_pcrb_check, params=PcrbParameters)
