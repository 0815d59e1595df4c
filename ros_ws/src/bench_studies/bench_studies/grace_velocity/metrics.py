"""The grace_velocity metric family ``range_rate`` (registered in tracking_bench.metrics).

Paper 002's yardstick (eq. 27): the range rate implied by an estimated baseline position b and velocity w,
rho_dot = b . w / |b|, minus the K-band ranging (KBR) range rate of the same step: std, mean, max and min over
the day. The bench also has the truth, which the paper did not: the same residual against the true range rate
(the KBR's own noise removed), the baseline velocity error and, for the filters and smoothers, the NEES of the
baseline position and velocity (``baseline_nees``, 6 dof, with the 95 % band of its effective samples:
bench_eval.metrics.effective_samples, and each run's own time average, ``baseline_nees_runs``): whether each
filter's covariance tells the truth about its error.

Options (``scoring`` section): ``kbr`` (the KBR sensor, default "kbr"), ``baseline`` (the six baseline labels,
position then velocity) and ``pairs`` (name: [second satellite's estimator, first's]: a baseline formed from two
single-satellite estimators). Which steps are scored is not the family's choice: the scorer hands it the runs cut
to the scenario's scoring window, the same steps for every estimator (bench_eval.window).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import chdtri  # chi-square quantile: chi2.ppf(q, k) = chdtri(k, 1 - q)

from bench_engine.config import ScenarioError
from bench_engine.settings import Check, Settings, setting
from bench_eval.metric_families import Metric, Tracks
from bench_eval.metrics import covariance_block, effective_samples
from bench_eval.scoring import BagData

STATS = ("std", "mean", "max", "min", "rms")


@dataclass(frozen=True, kw_only=True)
class RangeRateOptions(Settings):
    """The ``range_rate`` family's keys of the ``scoring`` section."""

    kbr: str = setting("kbr", doc="the K-band ranging sensor the range rates are compared with")
    baseline: list[str] = setting(
        doc="the baseline's labels: position, then velocity",
        check=Check(lambda v: len(v) == 6, "6 labels (position, velocity)"),
    )
    pairs: dict = setting(
        {},
        doc="NAME: [second, first]: the difference of two estimators' satellite states, "
        "scored as the baseline estimate NAME",
    )

    def validate(self, path: str) -> None:
        for name, members in self.pairs.items():
            if not isinstance(members, list) or len(members) != 2:
                raise ScenarioError(f"'{path}.pairs.{name}' must name two estimators [second, first]")


BASELINE = ["bx", "by", "bz", "bvx", "bvy", "bvz"]
"""The baseline's labels (truth and estimates): position, then velocity."""


def range_rate(b: np.ndarray, w: np.ndarray) -> np.ndarray:
    """rho_dot = b . w / |b| (paper 002, eq. 27) per row."""
    return np.sum(b * w, axis=-1) / np.linalg.norm(b, axis=-1)


def range_rate_sd(b: np.ndarray, w: np.ndarray, P: np.ndarray) -> np.ndarray:
    """sqrt(g' P g) per row for baselines b, w (K, 3) and their covariance P (K, 6, 6): the standard deviation of
    rho_dot mapped by its gradient g = [(w - rho_dot b_hat) / |b|, b_hat] (bench_studies.grace_velocity.bounds)."""
    rng = np.linalg.norm(b, axis=1, keepdims=True)
    b_hat = b / rng
    g = np.hstack([(w - range_rate(b, w)[:, None] * b_hat) / rng, b_hat])
    return np.sqrt(np.einsum("ki,kij,kj->k", g, P, g))


def _columns(labels: list[str], wanted: list[str]) -> list[int] | None:
    return [labels.index(w) for w in wanted] if all(w in labels for w in wanted) else None


def baseline_states(data: BagData, name: str, options: RangeRateOptions) -> tuple | None:
    """(steps, t, [b w] (K, 6), covariance (K, 6, 6) or None) of estimator ``name`` (or of a pair's
    difference, without covariance), None when it has no baseline."""
    if name in options.pairs:
        second, first = (data.estimates.get(n) for n in options.pairs[name])
        if second is None or first is None:
            return None
        common, i2, i1 = np.intersect1d(second.steps, first.steps, return_indices=True)
        cols = [
            _columns(e.labels, [lab.replace("b", "", 1) + suffix for lab in options.baseline])
            for e, suffix in ((second, "2"), (first, "1"))
        ]
        if None in cols:
            return None
        return common, second.t[i2], second.x[i2][:, cols[0]] - first.x[i1][:, cols[1]], None
    est = data.estimates.get(name)
    cols = None if est is None else _columns(est.labels, options.baseline)
    if cols is None:
        return None
    P = covariance_block(est.P, cols)
    return est.steps, est.t, est.x[:, cols], (P if np.all(np.isfinite(P)) else None)


def residuals(data: BagData, name: str, options: RangeRateOptions) -> dict[str, np.ndarray] | None:
    """Per KBR step with an estimate: t (s from the run's start), rho_dot_est - rho_dot_KBR, rho_dot_est -
    rho_dot_true, baseline velocity error (K, 3) and, for an estimator with a covariance, the baseline NEES (K,)
    (6 dof: position and velocity)."""
    states = baseline_states(data, name, options)
    kbr = data.measurements.get(options.kbr, {})
    if states is None or not kbr:
        return None
    steps, t, bw, P = states
    t0 = data.truth_span()[0]
    keep = np.flatnonzero(np.isin(steps, np.fromiter(kbr, dtype=np.int64, count=len(kbr))))
    covered, _, truth = data.truth_at(steps[keep])
    keep = keep[covered]
    if not len(keep):
        return None
    truth = truth[:, _columns(data.truth_labels, options.baseline)]
    rr = range_rate(bw[keep, :3], bw[keep, 3:])
    z = np.array([kbr[k][-1] for k in steps[keep].tolist()])
    out = {
        "t": t[keep] - t0,
        "kbr": rr - z,
        "truth": rr - range_rate(truth[:, :3], truth[:, 3:]),
        "velocity": bw[keep, 3:] - truth[:, 3:],
    }
    if P is not None:
        err = bw[keep] - truth
        out["nees"] = np.einsum("ki,ki->k", err, np.linalg.solve(P[keep], err[..., None])[..., 0])
    return out


def _stats(x: np.ndarray) -> dict[str, float]:
    return {
        "std": float(np.std(x)),
        "mean": float(np.mean(x)),
        "max": float(np.max(x)),
        "min": float(np.min(x)),
        "rms": float(np.sqrt(np.mean(x * x))),
    }


def _score_one(per_run: list[dict]) -> dict:
    out: dict = {"runs": len(per_run)}
    for key in ("kbr", "truth"):
        stats = [_stats(r[key]) for r in per_run]
        out[f"rr_{key}"] = {s: float(np.mean([st[s] for st in stats])) for s in STATS}
        out[f"rr_{key}_runs"] = {s: [st[s] for st in stats] for s in STATS}
    vel = [float(np.sqrt(np.mean(np.sum(r["velocity"] ** 2, axis=1)))) for r in per_run]
    out["velocity_rmse"] = float(np.mean(vel))
    out["velocity_rmse_runs"] = vel
    if all("nees" in r for r in per_run):
        # the time-averaged baseline NEES; 6 dof, its 95 % band for the runs' effective samples (chi-square /
        # samples): the steps of a run are far from independent (bench_eval.metrics.effective_samples)
        samples = effective_samples([r["nees"] for r in per_run])
        out["baseline_nees"] = float(np.mean(np.concatenate([r["nees"] for r in per_run])))
        out["baseline_nees_runs"] = [float(np.mean(r["nees"])) for r in per_run]
        out["baseline_nees_samples"] = float(samples)
        out["baseline_nees_bounds"] = [float(chdtri(6 * samples, 1.0 - q) / samples) for q in (0.025, 0.975)]
    return out


def _names(tracks: Tracks, runs: list[BagData], options: RangeRateOptions) -> list[str]:
    names = list(tracks) + [p for p in options.pairs if p not in tracks]
    return [n for n in names if baseline_states(runs[0], n, options) is not None]


def _score(tracks: Tracks, runs: list[BagData], options: RangeRateOptions) -> dict:
    scores = {}
    for name in _names(tracks, runs, options):
        per_run = [r for r in (residuals(d, name, options) for d in runs) if r is not None]
        if per_run:
            scores[name] = _score_one(per_run)
    floor = [f for f in (_kbr_noise(d, options) for d in runs) if f is not None]
    for block in scores.values():
        block["kbr_noise_std"] = float(np.mean(floor)) if floor else float("nan")
    return scores


def _kbr_noise(data: BagData, options: RangeRateOptions) -> float | None:
    """The std of the KBR's own error (KBR minus the true range rate): the floor of any residual against it."""
    kbr = data.measurements.get(options.kbr, {})
    cols = _columns(data.truth_labels, options.baseline)
    if not kbr or cols is None:
        return None
    steps = np.fromiter(kbr, dtype=np.int64, count=len(kbr))
    covered, _, truth = data.truth_at(steps)
    baseline = truth[:, cols]
    z = np.array([kbr[k][-1] for k in steps[covered].tolist()])
    return float(np.std(z - range_rate(baseline[:, :3], baseline[:, 3:])))


def range_rate_bound(data: BagData, series) -> np.ndarray:
    """A bound on the baseline (bench_eval.bounds.BoundSeries over BASELINE) mapped to the range rate at the
    truth: its standard deviation's bound (K,) at the series' steps."""
    cols = [data.truth_labels.index(c) for c in BASELINE]
    truth = np.array([data.truth[int(k)][1][cols] for k in series.steps])
    return range_rate_sd(truth[:, :3], truth[:, 3:], series.P)


def range_rate_bounds(data: BagData) -> dict[str, dict[str, np.ndarray]]:
    """Each bound on the baseline that ``data`` was scored against (bench_eval.bounds: ``data.bounds``) mapped
    to the range rate at the truth: {bound: {t (s from the first truth step), sd}}."""
    if _columns(data.truth_labels, BASELINE) is None:
        return {}
    t0 = data.truth_span()[0]
    return {
        name: {"t": series.t - t0, "sd": range_rate_bound(data, series)}
        for name, series in (data.bounds or {}).items()
        if list(series.labels) == BASELINE
    }


def _series(tracks: Tracks, runs: list[BagData], options: RangeRateOptions) -> dict:
    """First run's residual time series per estimator (plots over the day), each with the first run's bounds
    on the range rate (``rr_bounds``: the same for every estimator)."""
    out = {}
    bounds = range_rate_bounds(runs[0])
    for name in _names(tracks, runs, options):
        r = residuals(runs[0], name, options)
        if r is not None:
            out[name] = {"t": r["t"], "kbr": r["kbr"], "truth": r["truth"], "rr_bounds": bounds}
    return out


RANGE_RATE = Metric(options=RangeRateOptions, score=_score, series=_series)
