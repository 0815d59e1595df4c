"""Scoring metrics: eq. 35 RMSE, Table 2 summary, NEES consistency, radar-coordinate RMSE, formation metrics."""

import json

import numpy as np
import pytest
from scipy.stats import chi2

from bench_eval.metrics import (
    Track,
    axes_settling_time,
    convergence_series,
    effective_samples,
    fraction_within_sigma,
    mean_absolute_error,
    nees,
    nees_series,
    nees_summary,
    rmse_over_runs,
    score_convergence,
    score_errors,
    settling_time,
    summarise,
    time_grid,
)
from bench_studies.leo_radar.metrics import RadarSamples, radar_coordinate_rmse, score_radar_convergence

LABELS = ["x", "y", "z", "vx", "vy", "vz"]


def track_from_errors(t, err, P=None):
    """Track whose truth is zero, so x_est is the error."""
    t = np.asarray(t, dtype=float)
    err = np.asarray(err, dtype=float)
    if P is None:
        P = np.tile(np.eye(err.shape[1]), (len(t), 1, 1))
    return Track(t, err, P, np.zeros_like(err), LABELS[: err.shape[1]])


def test_rmse_hand_computed_with_missing_step_and_stamp_jitter():
    run1 = track_from_errors([100.0, 100.1], [[3, 4, 0], [1, 0, 0]])
    run2 = track_from_errors([100.0 + 1e-7], [[0, 0, 5]])  # misses the second step
    t, r = rmse_over_runs([run1, run2])
    np.testing.assert_allclose(t, [100.0, 100.1])
    np.testing.assert_allclose(r, [5.0, 1.0])  # sqrt((25 + 25) / 2), then run 1 alone
    _, rx = rmse_over_runs([run1, run2], ["x"])
    np.testing.assert_allclose(rx, [np.sqrt(9 / 2), 1.0])


def test_rmse_single_run_is_error_norm_and_truth_is_subtracted():
    rng = np.random.default_rng(1)
    t = np.arange(50) * 0.1
    x_true = rng.normal(size=(50, 6)) * 1e6
    err = rng.normal(size=(50, 6))
    tr = Track(t, x_true + err, np.tile(np.eye(6), (50, 1, 1)), x_true, LABELS)
    _, r = rmse_over_runs([tr])
    np.testing.assert_allclose(r, np.linalg.norm(err[:, :3], axis=1), rtol=1e-9)


def test_time_grid_rejects_two_stamps_in_one_step_and_bad_tracks():
    with pytest.raises(ValueError):
        time_grid([np.array([0.0, 0.0005])], tol=1e-3)
    with pytest.raises(ValueError):
        Track(np.arange(3.0), np.zeros((3, 6)), np.zeros((3, 6, 6)), np.zeros((2, 6)), LABELS)
    with pytest.raises(ValueError):
        Track(np.array([0.0, 0.0, 1.0]), np.zeros((3, 6)), np.zeros((3, 6, 6)), np.zeros((3, 6)), LABELS)


def decaying_curve(seed=2):
    """RMSE-like curve: 600 m floor + 30 km transient decaying with tau = 5 s, 5 % multiplicative noise."""
    rng = np.random.default_rng(seed)
    t = 1000.0 + np.arange(0.0, 300.0, 0.1)
    r = (600.0 + 30000.0 * np.exp(-(t - 1000.0) / 5.0)) * (1.0 + 0.05 * rng.standard_normal(len(t)))
    return t, r


def test_summarise_decaying_curve():
    t, r = decaying_curve()
    s = summarise(t, r)
    # threshold 1.5 x 600 = 900 m: 30000 exp(-t/5) = 300 at t = 5 ln 100 = 23.03 s
    assert s["threshold"] == pytest.approx(900.0, rel=0.02)
    assert s["convergence_time_s"] == pytest.approx(5.0 * np.log(100.0), abs=1.0)
    assert s["converged"] == pytest.approx(600.0, abs=10.0)
    lo, hi = s["band"]  # 5th / 95th percentiles of 600 (1 + 0.05 N(0,1)) = 600 (1 -/+ 0.082) = 551 / 649,
    # the upper one lifted ~10 m by the end of the transient just after convergence
    assert lo == pytest.approx(600.0 * (1 - 1.645 * 0.05), abs=8.0)
    assert 649.0 < hi < 665.0
    assert s["peak"] == r.max() and s["peak_time_s"] < 0.5
    tight = summarise(t, r, threshold=700.0)  # 30000 exp(-t/5) = 100 -> 28.5 s, later than the default
    assert tight["convergence_time_s"] > s["convergence_time_s"] + 3.0
    full = summarise(t, r, band_percentiles=(0.0, 100.0))
    k = np.searchsorted(t - t[0], full["convergence_time_s"] - 1e-9)
    assert full["band"] == [r[k:].min(), r[k:].max()]


def test_summarise_not_converged_and_single_run_smoothing():
    t = np.arange(0.0, 100.0, 0.1)
    rising = 100.0 + t
    s = summarise(t, rising, threshold=150.0)
    assert np.isnan(s["convergence_time_s"]) and np.isnan(s["converged"])
    # one run: per-step error norm of a 3-D Gaussian (chi-distributed) on top of the decay
    rng = np.random.default_rng(3)
    sigma = 600.0 / np.sqrt(3.0) * (1.0 + 50.0 * np.exp(-t / 5.0))
    r = np.linalg.norm(rng.standard_normal((len(t), 3)), axis=1) * sigma
    raw = summarise(t, r)
    smooth = summarise(t, r, smooth_s=10.0)
    # raw chi noise keeps crossing 1.5 x median to the very end (NaN) or nearly
    assert np.isnan(raw["convergence_time_s"]) or raw["convergence_time_s"] > 40.0
    # windowed RMS: 1 + 50 exp(-t/5) = 1.5 at 5 ln 100 = 23.0 s, the 10 s window smears it by ~1 s
    assert smooth["convergence_time_s"] == pytest.approx(5.0 * np.log(100.0), abs=2.5)


def gaussian_runs(n_runs, k, scale_reported, seed):
    """Runs whose errors are drawn from P_true; the filter reports scale_reported * P_true."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(6, 6))
    P_true = A @ A.T + 6.0 * np.eye(6)
    L = np.linalg.cholesky(P_true)
    t = np.arange(k) * 0.1
    return [
        track_from_errors(t, rng.standard_normal((k, 6)) @ L.T, np.tile(scale_reported * P_true, (k, 1, 1)))
        for _ in range(n_runs)
    ]


def test_nees_consistent_and_overconfident():
    good = nees_summary(gaussian_runs(40, 300, 1.0, seed=4))
    assert good["mean"] == pytest.approx(6.0, abs=0.15)
    assert good["bounds"] == pytest.approx([chi2.ppf(0.025, 240) / 40, chi2.ppf(0.975, 240) / 40])
    assert 0.9 <= good["fraction_inside"] <= 0.99
    bad = nees_summary(gaussian_runs(40, 300, 0.25, seed=4))  # covariance 4x too small
    assert bad["mean"] == pytest.approx(24.0, rel=0.05)
    assert bad["fraction_inside"] < 0.01


def test_nees_hand_value_sub_block_and_per_step_bounds():
    P = np.diag([4.0, 9.0, 1.0, 1.0, 1.0, 1.0])[None]
    tr = Track([0.0], [[2.0, 3.0, 0.0, 5.0, 0.0, 0.0]], P, np.zeros((1, 6)), LABELS)
    assert nees(tr)[0] == pytest.approx(1.0 + 1.0 + 25.0)
    assert nees(tr, ["x", "y"])[0] == pytest.approx(2.0)
    runs = [track_from_errors([0.0, 1.0], np.zeros((2, 6))), track_from_errors([0.0], np.zeros((1, 6)))]
    s = nees_series(runs)
    np.testing.assert_array_equal(s["runs"], [2, 1])
    assert s["hi"][1] == pytest.approx(chi2.ppf(0.975, 6))
    assert s["hi"][0] == pytest.approx(chi2.ppf(0.975, 12) / 2)


def test_radar_rmse_wraps_angles_across_zero():
    two_pi = 2.0 * np.pi
    z_true = np.array([[1000.0, two_pi - 3e-4, 0.3], [2000.0, 1e-4, 0.2]])
    z_est = np.array([[1003.0, 1e-4, 0.3 + 4e-4], [1996.0, two_pi - 1e-4, 0.2]])
    z_meas = np.array([[1030.0, 3e-4, 0.3], [np.nan, np.nan, np.nan]])  # second scan missed
    r = radar_coordinate_rmse(z_est, z_meas, z_true, angle_indices=(1, 2))
    np.testing.assert_allclose(
        r["filter"], [np.sqrt((9 + 16) / 2), np.sqrt((16e-8 + 4e-8) / 2), np.sqrt(16e-8 / 2)], rtol=1e-6
    )
    np.testing.assert_allclose(r["measurement"], [30.0, 6e-4, 0.0], atol=1e-12)
    per_run = radar_coordinate_rmse([z_est[:1], z_est[1:]], [z_meas[:1], z_meas[1:]], [z_true[:1], z_true[1:]])
    np.testing.assert_allclose(per_run["filter"], r["filter"])


def test_mae_settling_time_and_sigma_fraction():
    t = np.arange(0.0, 200.0, 1.0)
    err = np.column_stack([10.0 * np.exp(-t / 20.0)] * 3 + [0.5 * np.exp(-t / 10.0)] * 3)
    run = track_from_errors(t, err)
    mae = mean_absolute_error([run, track_from_errors(t, -err)])
    assert mae["x"] == pytest.approx(np.mean(err[:, 0])) and mae["vz"] == pytest.approx(np.mean(err[:, 5]))
    assert mean_absolute_error([run], skip_s=100.0)["y"] == pytest.approx(np.mean(err[100:, 1]))
    # position: 10 exp(-t/20) <= 0.5 from t = 20 ln 20 = 59.9 s; velocity 0.5 exp(-t/10) <= 0.02 from 32.2 s
    assert axes_settling_time([run]) == pytest.approx(60.0)
    spiked = err.copy()
    spiked[120, 4] = 0.05
    assert axes_settling_time([track_from_errors(t, spiked)]) == pytest.approx(121.0)
    assert np.isnan(settling_time(t, np.full((len(t), 1), 1.0), [0.5]))
    P = np.tile(np.eye(2), (4, 1, 1))
    frac = fraction_within_sigma([track_from_errors(np.arange(4.0), [[0, 0], [1, -3.5], [2, 0], [-4, 0]], P)])
    assert frac == {"x": 0.75, "y": 0.75}


def test_score_leo_structure_and_consistency():
    tracks = {"ekf": gaussian_runs(5, 100, 1.0, seed=5), "ukf": gaussian_runs(5, 100, 2.0, seed=6)}
    z = np.array([[1000.0, 0.1, 0.2]] * 10)
    radar = {"ekf": RadarSamples(z + [1.0, 1e-4, 0.0], z + [30.0, 0.0, 2e-3], z)}
    scored = score_radar_convergence(tracks, radar)
    json.dumps(scored, allow_nan=False)
    ekf = scored["ekf"]
    t, r = rmse_over_runs(tracks["ekf"])
    assert ekf["rmse_peak_m"] == pytest.approx(r.max()) and ekf["runs"] == 5
    assert set(ekf["axes"]) == {"x", "y", "z"} and len(ekf["axes"]["z"]["band_m"]) == 2
    assert ekf["radar"]["filter"] == pytest.approx({"range_m": 1.0, "azimuth_mrad": 0.1, "elevation_mrad": 0.0})
    assert ekf["radar"]["measurement"]["elevation_mrad"] == pytest.approx(2.0)
    assert "radar" not in scored["ukf"] and scored["ukf"]["nees_mean"] < scored["ekf"]["nees_mean"]
    series = convergence_series(tracks)
    assert series["ekf"]["t"][0] == 0.0 and series["ukf"]["nees"]["dof"] == 6


def test_each_runs_own_convergence_time():
    """Per-run convergence times (the spread behind the convergence-time claim's standard error): a position
    error 1000 exp(-t/tau) + 10 m per axis settles below 1.5 x its 10 m floor at tau ln(200); the later run's
    time counts from the earliest first stamp, as the pooled curve's does."""
    t = np.arange(0.0, 120.0, 0.1)
    runs = [
        track_from_errors(t + start, np.column_stack([1000.0 * np.exp(-t / tau) + 10.0] * 3 + [0.0 * t] * 3))
        for tau, start in ((5.0, 0.0), (10.0, 2.0))
    ]
    got = score_convergence({"f": runs})["f"]["convergence_time_s_runs"]
    assert got == pytest.approx([5.0 * np.log(200.0), 2.0 + 10.0 * np.log(200.0)], abs=0.6)


def test_score_formation_is_json_ready():
    scored = score_errors({"pf": gaussian_runs(3, 50, 1.0, seed=7)})
    json.dumps(scored, allow_nan=False)
    assert scored["pf"]["settling_time_s"] is None  # stationary unit-scale errors never go under 0.02 m/s
    assert set(scored["pf"]["mae"]) == set(LABELS)


def test_effective_samples_count_independent_samples_not_steps():
    """White noise is worth its length; an AR(1) series with phi = 0.9 about (1 - phi) / (1 + phi) of it; a smooth
    error (two periods of a sine, as a fitted orbit's) almost nothing; and many runs of white noise their total."""
    rng = np.random.default_rng(3)
    n = 20000
    assert 0.9 * n < effective_samples([rng.standard_normal(n)]) <= n
    assert 0.9 * n < effective_samples(list(rng.standard_normal((8, n // 8)))) <= n
    ar = np.zeros(n)
    w = rng.standard_normal(n)
    for k in range(1, n):
        ar[k] = 0.9 * ar[k - 1] + w[k]
    assert effective_samples([ar]) == pytest.approx(n * 0.1 / 1.9, rel=0.25)
    smooth = np.sin(np.linspace(0.0, 4.0 * np.pi, n)) ** 2 + 1e-3 * rng.standard_normal(n)
    assert effective_samples([smooth]) < n / 500


def test_runs_that_sit_at_their_own_levels_are_worth_about_one_sample_each():
    """A fitted orbit's NEES oscillates within a run about a level set by that run's parameter error: each run's
    own autocorrelation, taken about its own mean, would count about 50 samples a run here;
    the spread of the runs' levels says the batch is worth about one sample per run. Runs at one common level
    (a filter's) still count their steps."""
    rng = np.random.default_rng(5)
    runs, n = 20, 8640
    phase = np.linspace(0.0, 32.0 * np.pi, n)
    levels = rng.chisquare(6, runs)
    fitted = [level + 0.3 * level * np.sin(phase + rng.uniform(0, 6.3)) for level in levels]
    assert 0.3 * runs < effective_samples(fitted) <= 1.2 * runs
    assert effective_samples(fitted[:1]) > 10  # one run alone cannot see its own level
    steady = [6.0 + rng.standard_normal(n) for _ in range(runs)]
    assert effective_samples(steady) > 0.9 * runs * n
