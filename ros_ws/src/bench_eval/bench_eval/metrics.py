"""Scoring metrics: Monte Carlo RMSE and its summary, NEES consistency, measurement-space RMSE, error statistics.

Longer than 500 lines: the metric functions and the two families built from them (convergence and errors),
which use them and nothing else.

Two families of scores are built from them (registered in bench_eval.metric_families):
- convergence (:func:`score_convergence`): position RMSE over N Monte Carlo runs per time step (paper 000
  eq. 35), summarised by the peak, the time to converge, the band the error "wanders in" after convergence
  and the converged RMSE value (operational definitions in :func:`summarise`), per axis as well; NEES (a
  study's family adds its own scores to these blocks).
- errors (:func:`score_errors`): mean absolute error per state component (with each run's value for Monte
  Carlo error bars and paired comparisons), the time after which every position and velocity axis stays
  below a threshold, the fraction of errors inside +-3 sigma, NEES.

Errors are taken by each state's own rule (bench_models.states: a quaternion block as a rotation vector,
angles wrapped); a Track's covariance is in the space of its error labels.

Runs are aligned on a common time grid: the union of all estimate stamps, stamps closer than ``tol`` seconds
being the same step. A run that misses a step (e.g. a missed detection) simply does not contribute to it.
Every ``score_*`` function returns plain Python containers (floats, lists, ``None`` for undefined values),
ready for ``json.dump(..., allow_nan=False)``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.special import chdtri  # chi-square quantile: chi2.ppf(q, k) = chdtri(k, 1 - q)

from bench_engine.labels import POSITION, VELOCITY
from bench_models.states import error_labels, state_error

Components = Sequence[str | int]
DEFAULT_TOL_S = 1e-3


def covariance_block(P: np.ndarray, index: list[int]) -> np.ndarray:
    """The block of covariances P (K, n, n) of the components ``index``: a view, not a copy, when they are
    consecutive (an orbit fit's 12 position and velocity components of its 18)."""
    if index and index == list(range(index[0], index[-1] + 1)):
        return P[:, index[0] : index[-1] + 1, index[0] : index[-1] + 1]
    return P[:, index][:, :, index]


@dataclass
class Track:
    """One filter in one run, aligned to the estimate stamps."""

    t: np.ndarray
    """(K,) estimate times [s], strictly increasing."""
    x_est: np.ndarray
    """(K, n) estimated states."""
    P: np.ndarray
    """(K, n, n) estimate covariances."""
    x_true: np.ndarray
    """(K, n) truth at the same stamps, same labels and frame."""
    labels: list[str]

    def __post_init__(self) -> None:
        self.t = np.asarray(self.t, dtype=float)
        self.x_est = np.asarray(self.x_est, dtype=float)
        self.P = np.asarray(self.P, dtype=float)
        self.x_true = np.asarray(self.x_true, dtype=float)
        self.labels = list(self.labels)
        k, n, m = len(self.t), len(self.labels), len(error_labels(self.labels))
        if self.x_est.shape != (k, n) or self.x_true.shape != (k, n) or self.P.shape != (k, m, m):
            raise ValueError(
                f"Track shapes disagree: t {self.t.shape}, x_est {self.x_est.shape}, "
                f"x_true {self.x_true.shape}, P {self.P.shape}, {n} labels"
            )
        if k > 1 and np.any(np.diff(self.t) <= 0.0):
            raise ValueError("Track stamps must be strictly increasing")

    @property
    def error_labels(self) -> list[str]:
        """Labels of the error vector (a quaternion block becomes rx, ry, rz: bench_models.states)."""
        return error_labels(self.labels)

    def indices(self, components: Components | None = None) -> list[int]:
        """Error-vector indices of the given labels or indices (all components when None)."""
        if components is None:
            return list(range(len(self.error_labels)))
        return [c if isinstance(c, (int, np.integer)) else self.error_labels.index(c) for c in components]

    def error(self, components: Components | None = None) -> np.ndarray:
        """Estimation error of the selected components by the state's own rule, shape (K, c)."""
        _, e = state_error(self.labels, self.x_est, self.x_true)
        return e[:, self.indices(components)]


def time_grid(stamps: Sequence[np.ndarray], tol: float = DEFAULT_TOL_S) -> tuple[np.ndarray, list[np.ndarray]]:
    """Union of the runs' stamps and, for each run, the grid index of each of its stamps.

    Sorted stamps less than ``tol`` apart belong to one grid step (its time is the earliest of them).
    Raises ValueError if one run has two stamps in the same step (``tol`` too large for its rate).
    """
    # each run's stamps are in order: a stable sort (timsort) merges those runs instead of sorting afresh
    everything = np.sort(np.concatenate([np.asarray(s, dtype=float) for s in stamps]), kind="stable")
    starts = everything[np.concatenate(([True], np.diff(everything) > tol))]
    index = [np.searchsorted(starts, s, side="right") - 1 for s in stamps]
    for i in index:
        if len(i) > 1 and np.any(np.diff(i) == 0):
            raise ValueError(f"a run has two stamps within tol={tol} s of one grid step")
    return starts, index


def on_grid(
    tracks: Sequence[Track], values: Sequence[np.ndarray], tol: float = DEFAULT_TOL_S
) -> tuple[np.ndarray, np.ndarray]:
    """Place per-track arrays (K_i, ...) on the common grid: (t_grid (G,), stacked (N, G, ...) NaN-filled)."""
    grid, index = time_grid([tr.t for tr in tracks], tol)
    tail = np.shape(values[0])[1:]
    stacked = np.full((len(tracks), len(grid)) + tail, np.nan)
    for run, (idx, v) in enumerate(zip(index, values)):
        stacked[run, idx] = v
    return grid, stacked


def rmse_over_runs(
    tracks: Sequence[Track], components: Components = POSITION, tol: float = DEFAULT_TOL_S
) -> tuple[np.ndarray, np.ndarray]:
    """RMSE per time step over the Monte Carlo runs (paper 000 eq. 35).

    rmse_k = sqrt( (1/N_k) sum_i |e_k^i|^2 ) over the selected components, N_k being the number of runs that
    have step k. With one component it is the per-axis RMSE; with N = 1 it is the per-step error norm.
    Returns (t_grid (G,), rmse (G,)).
    """
    grid, sq = on_grid(tracks, [np.sum(tr.error(components) ** 2, axis=1) for tr in tracks], tol)
    return grid, np.sqrt(np.nanmean(sq, axis=0))


def windowed_rms(t: np.ndarray, values: np.ndarray, window_s: float) -> np.ndarray:
    """Centred moving RMS of ``values`` over ``window_s`` seconds (works on uneven stamps)."""
    lo = np.searchsorted(t, t - 0.5 * window_s, side="left")
    hi = np.searchsorted(t, t + 0.5 * window_s, side="right")
    csum = np.concatenate(([0.0], np.cumsum(np.asarray(values, dtype=float) ** 2)))
    return np.sqrt((csum[hi] - csum[lo]) / (hi - lo))


def first_settled_index(exceeds: np.ndarray) -> int:
    """Index of the first step after which ``exceeds`` is False to the end (len if the last step exceeds)."""
    bad = np.flatnonzero(exceeds)
    return 0 if bad.size == 0 else int(bad[-1]) + 1


def summarise(
    t: np.ndarray,
    rmse: np.ndarray,
    *,
    t0: float | None = None,
    tail_fraction: float = 0.5,
    threshold_factor: float = 1.5,
    threshold: float | None = None,
    band_percentiles: tuple[float, float] = (5.0, 95.0),
    smooth_s: float = 0.0,
) -> dict:
    """Peak, convergence time, band and converged level of an RMSE curve (paper 000 Table 2).

    Operational definitions (the paper reads these off its Fig. 6 without defining them):
    - reference level L: median of the RMSE over the last ``tail_fraction`` of the time span;
    - threshold: ``threshold`` if given, else ``threshold_factor * L``;
    - convergence time: first time after which the RMSE stays below the threshold to the end, measured from
      ``t0`` (default: the first stamp). On a steep decay (35 km -> 650 m) it is insensitive to the factor;
    - band ("roughness"): the [low, high] percentiles of the RMSE after convergence (``(0, 100)`` gives the
      min-max reading);
    - converged: the mean RMSE after convergence (paper: 645 m inside its 600-700 m band);
    - peak: the maximum RMSE over the whole curve, and its time from ``t0``.
    ``smooth_s`` > 0 tests the threshold on a centred moving RMS of that width, which a single run (N = 1,
    chi-distributed per-step errors) needs; band and converged level always use the raw curve.
    If the curve ends above the threshold, convergence time, band and converged level are NaN.
    """
    t = np.asarray(t, dtype=float)
    rmse = np.asarray(rmse, dtype=float)
    t0 = float(t[0]) if t0 is None else t0
    tested = windowed_rms(t, rmse, smooth_s) if smooth_s > 0.0 else rmse
    tail = t >= t[-1] - tail_fraction * (t[-1] - t[0])
    level = float(np.median(tested[tail]))
    thr = threshold_factor * level if threshold is None else threshold
    k = first_settled_index(tested > thr)
    ipeak = int(np.argmax(rmse))
    out = {
        "peak": float(rmse[ipeak]),
        "peak_time_s": float(t[ipeak] - t0),
        "threshold": float(thr),
        "convergence_time_s": np.nan,
        "band": [np.nan, np.nan],
        "converged": np.nan,
    }
    if k < len(t):
        after = rmse[k:]
        out.update(
            convergence_time_s=float(t[k] - t0),
            band=[float(b) for b in np.percentile(after, band_percentiles)],
            converged=float(np.mean(after)),
        )
    return out


def nees(track: Track, components: Components | None = None) -> np.ndarray:
    """Normalised estimation error squared e^T P^-1 e per step, shape (K,), over the selected sub-block."""
    idx = track.indices(components)
    e = track.error(idx)
    P = track.P[:, idx][:, :, idx]
    return np.einsum("ki,ki->k", e, np.linalg.solve(P, e[:, :, None])[:, :, 0])


def effective_samples(runs: Sequence[np.ndarray]) -> float:
    """The number of independent samples a batch of runs of one stationary series is worth (the multi-run
    effective sample size of Gelman et al., "Bayesian Data Analysis", 3rd ed., section 11.5, as Stan computes
    it): the steps over tau = 1 + 2 sum_t rho_t. The autocorrelation at lag t is pooled over the M runs,

        rho_t = 1 - (W - mean_m gamma_m(t)) / var+,   var+ = (n - 1) / n W + B / n,

    W the mean within-run variance, B / n the variance of the run means and gamma_m(t) run m's autocovariance
    (the runs cut to the shortest's n steps), and summed in Geyer's (1992) initial positive, monotone sequence of
    pairs rho_2k + rho_2k+1. A filter's NEES decorrelates within seconds. A fitted orbit's error is a smooth
    function of a few parameters per run: within a run its NEES oscillates about a level set by that run's
    parameter error, which a run's own autocorrelation (taken about its own mean) cannot see; the spread of the
    runs' means does, and a batch of such runs is worth about one sample per run. A chi-square band for a time
    average must count these samples, not the steps."""
    x = [np.asarray(r, dtype=float) for r in runs if len(r)]
    total = sum(len(r) for r in x)
    n = min((len(r) for r in x), default=0)
    if n < 4:
        return float(total)
    chains = np.stack([r[:n] for r in x])
    means = chains.mean(axis=1)
    centred = chains - means[:, None]
    spectrum = np.fft.rfft(centred, 2 * n, axis=1)
    acov = np.fft.irfft(spectrum * np.conj(spectrum), axis=1)[:, :n] / n
    within = float(np.mean(acov[:, 0])) * n / (n - 1)
    var_plus = within * (n - 1) / n + (float(np.var(means, ddof=1)) if len(x) > 1 else 0.0)
    if var_plus <= 0.0:
        return float(total)
    rho = 1.0 - (within - acov.mean(axis=0)) / var_plus
    pairs = rho[: n - n % 2].reshape(-1, 2).sum(axis=1)
    ends = np.flatnonzero(pairs <= 0.0)
    pairs = np.minimum.accumulate(pairs[: ends[0] if len(ends) else len(pairs)])
    tau = -1.0 + 2.0 * float(np.sum(pairs))
    return total / max(tau, 1.0)


def nees_series(
    tracks: Sequence[Track], components: Components | None = None, alpha: float = 0.05, tol: float = DEFAULT_TOL_S
) -> dict:
    """Average NEES over runs per grid step and its two-sided (1 - alpha) chi-square bounds.

    For N_k runs at step k and n components, N_k * ANEES_k ~ chi2(N_k n) when the filter is consistent, so
    the bounds are chi2.ppf(alpha/2, N_k n) / N_k and chi2.ppf(1 - alpha/2, N_k n) / N_k.
    Returns dict(t, mean, lo, hi, runs (G,) and dof n).
    """
    grid, v = on_grid(tracks, [nees(tr, components) for tr in tracks], tol)
    runs = np.sum(~np.isnan(v), axis=0)
    n = len(tracks[0].indices(components))
    return {
        "t": grid,
        "mean": np.nanmean(v, axis=0),
        "runs": runs,
        "dof": n,
        "lo": chdtri(runs * n, 1.0 - 0.5 * alpha) / runs,
        "hi": chdtri(runs * n, 0.5 * alpha) / runs,
    }


def nees_summary(
    tracks: Sequence[Track],
    components: Components | None = None,
    alpha: float = 0.05,
    skip_s: float = 0.0,
    tol: float = DEFAULT_TOL_S,
) -> dict:
    """Time-averaged ANEES, the chi-square bounds for all N runs, and the fraction of steps inside their bounds.

    Steps earlier than ``skip_s`` after the first stamp are left out (initial transient). The fraction
    inside uses each step's own bounds (steps with fewer runs have wider bounds); a consistent filter has
    about 1 - alpha of its steps inside. Returns dict(mean, dof, runs, bounds [lo, hi], fraction_inside).
    """
    s = nees_series(tracks, components, alpha, tol)
    keep = s["t"] - s["t"][0] >= skip_s
    m, lo, hi = s["mean"][keep], s["lo"][keep], s["hi"][keep]
    n, runs = s["dof"], len(tracks)
    return {
        "mean": float(np.mean(m)),
        "dof": n,
        "runs": runs,
        "bounds": [float(chdtri(runs * n, 1.0 - 0.5 * alpha) / runs), float(chdtri(runs * n, 0.5 * alpha) / runs)],
        "fraction_inside": float(np.mean((m >= lo) & (m <= hi))),
    }


def mean_absolute_error(
    tracks: Sequence[Track], components: Components | None = None, skip_s: float = 0.0
) -> dict[str, float]:
    """Mean |error| per component over all runs and steps (paper 004 Tables 1-2).

    Steps earlier than ``skip_s`` after each run's first stamp are left out.
    """
    errs = [np.abs(tr.error(components))[tr.t - tr.t[0] >= skip_s] for tr in tracks]
    mae = np.mean(np.concatenate(errs, axis=0), axis=0)
    labels = [tracks[0].error_labels[i] for i in tracks[0].indices(components)]
    return {lab: float(v) for lab, v in zip(labels, mae)}


def mae_per_run(tracks: Sequence[Track], components: Components | None = None, skip_s: float = 0.0) -> np.ndarray:
    """Mean |x_est - x_true| per component of each run separately, shape (N, c) (paper 004 Tables 1-2).

    For runs of equal length the mean over runs equals :func:`mean_absolute_error`; the spread over runs
    gives the Monte Carlo standard error, and the same seeds across filters give paired differences.
    """
    return np.array([np.mean(np.abs(tr.error(components))[tr.t - tr.t[0] >= skip_s], axis=0) for tr in tracks])


def settling_time(t: np.ndarray, abs_err: np.ndarray, thresholds: Sequence[float], t0: float | None = None) -> float:
    """First time (from ``t0``, default the first stamp) after which every column of ``abs_err`` (G, c)
    stays at or below its threshold to the end; NaN if the last step is still above."""
    k = first_settled_index(np.any(abs_err > np.asarray(thresholds, dtype=float), axis=1))
    t0 = float(t[0]) if t0 is None else t0
    return float(t[k] - t0) if k < len(t) else float("nan")


def axes_settling_time(
    tracks: Sequence[Track],
    position_threshold: float = 0.5,
    velocity_threshold: float = 0.02,
    position: Components = POSITION,
    velocity: Components = VELOCITY,
    tol: float = DEFAULT_TOL_S,
) -> float:
    """Time after which every position axis error stays below ``position_threshold`` [m] and every velocity
    axis below ``velocity_threshold`` [m/s] (paper 001: 0.5 m and 0.02 m/s after 80 s).

    The per-axis error is the per-axis RMSE over runs (the absolute error for a single run).
    """
    comps = list(position) + list(velocity)
    curves = [rmse_over_runs(tracks, [c], tol) for c in comps]
    thresholds = [position_threshold] * len(position) + [velocity_threshold] * len(velocity)
    return settling_time(curves[0][0], np.column_stack([c[1] for c in curves]), thresholds)


def fraction_within_sigma(
    tracks: Sequence[Track], components: Components | None = None, k: float = 3.0
) -> dict[str, float]:
    """Fraction of steps (all runs) with |error_i| <= k sqrt(P_ii), per component (paper 004's 3-sigma check)."""
    idx = tracks[0].indices(components)
    inside = np.concatenate([np.abs(tr.error(idx)) <= k * np.sqrt(tr.P[:, idx, idx]) for tr in tracks])
    return {tracks[0].error_labels[i]: float(v) for i, v in zip(idx, np.mean(inside, axis=0))}


def json_ready(obj):
    """Recursively convert numpy scalars/arrays to Python floats/lists, NaN and inf to None."""
    if isinstance(obj, Mapping):
        return {str(k): json_ready(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, np.ndarray)):
        return [json_ready(v) for v in obj]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return float(obj) if np.isfinite(obj) else None
    return obj


def _curve_block(t: np.ndarray, rmse: np.ndarray, summary_kwargs: Mapping) -> dict:
    """Table 2 row for one RMSE curve, keys in metres and seconds."""
    s = summarise(t, rmse, **summary_kwargs)
    return {
        "rmse_converged_m": s["converged"],
        "rmse_peak_m": s["peak"],
        "peak_time_s": s["peak_time_s"],
        "convergence_time_s": s["convergence_time_s"],
        "band_m": s["band"],
        "threshold_m": s["threshold"],
    }


def score_convergence(
    tracks_by_filter: Mapping[str, Sequence[Track]],
    *,
    position: Components = POSITION,
    nees_skip_s: float = 0.0,
    alpha: float = 0.05,
    tol: float = DEFAULT_TOL_S,
    smooth_s: float = 1.0,
    **summary_kwargs,
) -> dict:
    """JSON-ready convergence scores per filter (paper 000 Tables 2 and 3 are of this form).

    Per filter: runs, rmse_converged_m, rmse_peak_m, peak_time_s, convergence_time_s, band_m [low, high],
    threshold_m, rmse_converged_m_runs and convergence_time_s_runs (per run), axes {x, y, z: same keys},
    nees_mean, nees_dof, nees_bounds [lo, hi], nees_fraction_inside (full-state NEES, see :func:`nees_summary`).
    ``smooth_s`` and ``summary_kwargs`` go to :func:`summarise`. The default 1 s window (10 scans at 10 Hz)
    keeps the convergence test robust when few runs are averaged (an RMSE over N runs of one Gaussian error
    component has a relative spread of about 1/sqrt(2N)) and shifts the convergence time by at most half
    the window.
    """
    summary_kwargs = {"smooth_s": smooth_s, **summary_kwargs}
    scored = {}
    for name, tracks in tracks_by_filter.items():
        block = {"runs": len(tracks), **_curve_block(*rmse_over_runs(tracks, position, tol), summary_kwargs)}
        block["rmse_converged_m_runs"] = converged_rms_per_run(tracks, block["convergence_time_s"], position)
        block["convergence_time_s_runs"] = convergence_time_per_run(tracks, position, tol, summary_kwargs)
        block["axes"] = {str(c): _curve_block(*rmse_over_runs(tracks, [c], tol), summary_kwargs) for c in position}
        ns = nees_summary(tracks, None, alpha, nees_skip_s, tol)
        block.update(
            nees_mean=ns["mean"],
            nees_dof=ns["dof"],
            nees_bounds=ns["bounds"],
            nees_fraction_inside=ns["fraction_inside"],
        )
        scored[name] = block
    return json_ready(scored)


def converged_rms_per_run(
    tracks: Sequence[Track], convergence_time_s: float, position: Components = POSITION
) -> list[float]:
    """Each run's RMS position error after the convergence time (measured from the earliest stamp of all
    runs): the spread of the converged RMSE over runs, for its Monte Carlo standard error."""
    if not np.isfinite(convergence_time_s):
        return []
    t0 = min(float(tr.t[0]) for tr in tracks)
    out = []
    for tr in tracks:
        after = tr.t - t0 >= convergence_time_s
        if np.any(after):
            out.append(float(np.sqrt(np.mean(np.sum(tr.error(position)[after] ** 2, axis=1)))))
    return out


def convergence_time_per_run(
    tracks: Sequence[Track],
    position: Components = POSITION,
    tol: float = DEFAULT_TOL_S,
    summary_kwargs: Mapping | None = None,
) -> list[float]:
    """Each run's own convergence time (:func:`summarise` of its position error, measured from the earliest
    stamp of all runs; NaN where it never settles): the spread over runs, for the Monte Carlo standard error
    of the convergence time."""
    t0 = min(float(tr.t[0]) for tr in tracks)
    return [
        summarise(*rmse_over_runs([tr], position, tol), t0=t0, **(summary_kwargs or {}))["convergence_time_s"]
        for tr in tracks
    ]


def convergence_series(
    tracks_by_filter: Mapping[str, Sequence[Track]],
    position: Components = POSITION,
    alpha: float = 0.05,
    tol: float = DEFAULT_TOL_S,
) -> dict:
    """Time series for the convergence plots, per filter: t (s from the earliest stamp of all filters),
    rmse (position), axes {x, y, z: rmse}, nees {t, mean, lo, hi, dof}."""
    t0 = min(float(tr.t[0]) for tracks in tracks_by_filter.values() for tr in tracks)
    series = {}
    for name, tracks in tracks_by_filter.items():
        t, r = rmse_over_runs(tracks, position, tol)
        ns = nees_series(tracks, None, alpha, tol)
        series[name] = {
            "t": t - t0,
            "rmse": r,
            "axes": {str(c): rmse_over_runs(tracks, [c], tol)[1] for c in position},
            "nees": {"t": ns["t"] - t0, "mean": ns["mean"], "lo": ns["lo"], "hi": ns["hi"], "dof": ns["dof"]},
        }
    return series


def below_after_per_run(
    tracks: Sequence[Track],
    after_s: float,
    position_threshold: float,
    velocity_threshold: float,
    position: Components = POSITION,
    velocity: Components = VELOCITY,
) -> list[bool]:
    """Per run: does every position axis stay within ``position_threshold`` and every velocity axis within
    ``velocity_threshold`` from ``after_s`` after its first stamp on (paper 001's "after 80 s")?"""
    thresholds = np.array([position_threshold] * len(position) + [velocity_threshold] * len(velocity))
    comps = list(position) + list(velocity)
    return [bool(np.all(np.abs(tr.error(comps))[tr.t - tr.t[0] >= after_s] <= thresholds)) for tr in tracks]


def score_errors(
    tracks_by_filter: Mapping[str, Sequence[Track]],
    *,
    skip_s: float = 0.0,
    position_threshold: float = 0.5,
    velocity_threshold: float = 0.02,
    hold_after_s: float | None = None,
    position: Components = POSITION,
    velocity: Components = VELOCITY,
    tol: float = DEFAULT_TOL_S,
) -> dict:
    """JSON-ready error statistics per filter (the form of papers 001 and 004's results), SI units.

    Per filter: runs, mae {component: m or m/s}, mae_runs {component: [each run's MAE]} (the Monte Carlo
    spread; the same seeds across filters give paired differences), settling_time_s, within_3sigma
    {component: fraction}, nees_mean, nees_dof, nees_bounds, nees_fraction_inside and, with
    ``hold_after_s``, below_after_runs (:func:`below_after_per_run`).
    """
    scored = {}
    comps = list(position) + list(velocity)
    for name, tracks in tracks_by_filter.items():
        ns = nees_summary(tracks, comps, skip_s=skip_s, tol=tol)
        scored[name] = {
            "runs": len(tracks),
            "mae": mean_absolute_error(tracks, comps, skip_s),
            "mae_runs": dict(zip(map(str, comps), mae_per_run(tracks, comps, skip_s).T)),
            "settling_time_s": axes_settling_time(
                tracks, position_threshold, velocity_threshold, position, velocity, tol
            ),
            "within_3sigma": fraction_within_sigma(tracks, comps),
            "nees_mean": ns["mean"],
            "nees_dof": ns["dof"],
            "nees_bounds": ns["bounds"],
            "nees_fraction_inside": ns["fraction_inside"],
        }
        if hold_after_s is not None:
            scored[name]["below_after_runs"] = below_after_per_run(
                tracks, hold_after_s, position_threshold, velocity_threshold, position, velocity
            )
    return json_ready(scored)
