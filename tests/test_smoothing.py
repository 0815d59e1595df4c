"""Fixed-interval RTS smoothing (tracker_filters.smoothing) and the offline-estimator stage of the scorer."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from graph_helpers import script
from scipy.linalg import block_diag, expm

from bench_engine.config import apply_overrides, load_scenario
from bench_engine.stage import Estimate
from bench_models.labelled import ComponentModel
from bench_models.white_jerk import WhiteJerkDynamics
from tracker_filters import registry
from tracker_filters.fixed_lag import FixedLagSmoother
from tracker_filters.smoothing import rts_smoother, smooth_estimates


def linear_problem(K: int = 12, seed: int = 0):
    """Constant-velocity model in 1-D, position measurements; returns prior, F, Q, H, R and measurements."""
    rng = np.random.default_rng(seed)
    dt = 0.7
    F = np.array([[1.0, dt], [0.0, 1.0]])
    Q = 0.05 * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    H, R = np.array([[1.0, 0.0]]), np.array([[0.3]])
    m0, P0 = np.array([0.0, 1.0]), np.diag([4.0, 1.0])
    x = rng.multivariate_normal(m0, P0)
    zs = []
    for _ in range(K):
        zs.append(H @ x + rng.normal(0.0, np.sqrt(R[0, 0]), 1))
        x = F @ x + rng.multivariate_normal(np.zeros(2), Q)
    return m0, P0, F, Q, H, R, np.array(zs)


def kalman(m0, P0, F, Q, H, R, zs):
    xs, Ps, x, P = [], [], m0, P0
    for k, z in enumerate(zs):
        if k:
            x, P = F @ x, F @ P @ F.T + Q
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        x, P = x + K @ (z - H @ x), (np.eye(2) - K @ H) @ P
        xs.append(x)
        Ps.append(P)
    return np.array(xs), np.array(Ps)


def batch_least_squares(m0, P0, F, Q, H, R, zs):
    """The joint posterior of x_0..x_K-1 by weighted least squares over prior, dynamics and measurements."""
    K, n = len(zs), len(m0)
    rows, rhs, weights = [], [], []
    first = np.zeros((n, K * n))
    first[:, :n] = np.eye(n)
    rows.append(first), rhs.append(m0), weights.append(P0)
    for k in range(K - 1):
        block = np.zeros((n, K * n))
        block[:, k * n : (k + 1) * n], block[:, (k + 1) * n : (k + 2) * n] = -F, np.eye(n)
        rows.append(block), rhs.append(np.zeros(n)), weights.append(Q)
    for k, z in enumerate(zs):
        block = np.zeros((1, K * n))
        block[:, k * n : (k + 1) * n] = H
        rows.append(block), rhs.append(z), weights.append(R)
    A, b, W = np.vstack(rows), np.concatenate(rhs), np.linalg.inv(block_diag(*weights))
    info = A.T @ W @ A
    cov = np.linalg.inv(info)
    mean = cov @ A.T @ W @ b
    return mean.reshape(K, n), np.array([cov[k * n : (k + 1) * n, k * n : (k + 1) * n] for k in range(K)])


def test_rts_equals_the_batch_least_squares_solution():
    m0, P0, F, Q, H, R, zs = linear_problem()
    xs, Ps = kalman(m0, P0, F, Q, H, R, zs)
    K = len(zs)
    x_s, P_s = rts_smoother(xs, Ps, np.repeat(F[None], K - 1, 0), np.repeat(Q[None], K - 1, 0))
    x_b, P_b = batch_least_squares(m0, P0, F, Q, H, R, zs)
    np.testing.assert_allclose(x_s, x_b, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(P_s, P_b, rtol=1e-8, atol=1e-10)
    np.testing.assert_array_equal(x_s[-1], xs[-1])  # the last filtered estimate is already smoothed
    assert np.all(np.linalg.eigvalsh(Ps[:-1] - P_s[:-1]) > -1e-12)  # smoothing never loses information


def test_rts_refuses_a_wrong_number_of_transitions():
    xs, Ps = np.zeros((3, 2)), np.repeat(np.eye(2)[None], 3, 0)
    with pytest.raises(ValueError, match="need 2 transitions"):
        rts_smoother(xs, Ps, np.repeat(np.eye(2)[None], 3, 0), np.repeat(np.eye(2)[None], 3, 0))


class TurningDynamics:
    """A 2-D state whose transition and process noise depend on the state and the step (to check that
    smooth_estimates pairs each estimate with the interval that follows it)."""

    labels, frame = ("a", "b"), "test"

    def transition_matrix(self, x: np.ndarray, dt: float) -> np.ndarray:
        c, s = np.cos(0.1 * x[0] * dt), np.sin(0.1 * x[0] * dt)
        return np.array([[c, dt * s], [-s / (1.0 + dt), c]])

    def process_noise(self, x: np.ndarray, dt: float) -> np.ndarray:
        return (0.01 + 0.001 * x[1] ** 2) * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])


def test_smooth_estimates_is_rts_with_the_dynamics_transitions_between_estimates():
    rng = np.random.default_rng(3)
    K, dynamics = 9, TurningDynamics()
    dts = rng.uniform(0.2, 2.0, K - 1)
    xs = rng.normal(size=(K, 2))
    L = rng.normal(size=(K, 2, 2))
    Ps = L @ L.transpose(0, 2, 1) + 0.1 * np.eye(2)
    Fs = np.array([dynamics.transition_matrix(xs[k], dts[k]) for k in range(K - 1)])
    Qs = np.array([dynamics.process_noise(xs[k], dts[k]) for k in range(K - 1)])
    x_s, P_s = smooth_estimates(dynamics, dts, xs, Ps)
    x_r, P_r = rts_smoother(xs, Ps, Fs, Qs)
    np.testing.assert_array_equal(x_s, x_r)
    np.testing.assert_array_equal(P_s, P_r)
    assert not np.allclose(x_s[:-1], xs[:-1])  # it did smooth
    x_1, P_1 = smooth_estimates(dynamics, dts[:0], xs[:1], Ps[:1])  # one estimate: nothing to smooth
    np.testing.assert_array_equal(x_1, xs[:1])
    np.testing.assert_array_equal(P_1, Ps[:1])


def test_the_scorer_runs_a_registered_offline_smoother_over_a_recorded_run(tmp_path: Path):
    res = script(
        "launch.py",
        "formation_cqkf",
        "--variant",
        "smoothed",
        "--estimators",
        "ss,cw",
        "--json",
        "--set",
        "time.duration=900",
        "--single-process",
        "--out",
        str(tmp_path),
    )
    assert res.returncode == 0, res.stderr[-2000:]
    filters = json.loads(res.stdout)["estimators"]
    assert set(filters) == {"ss", "cw", "ss_rts", "cw_rts"}  # cwb's smoother has no source in this run
    for name in ("ss", "cw"):
        assert filters[f"{name}_rts"]["runs"] == 1
        for axis in ("x", "y", "z", "vx", "vy", "vz"):  # the smoothed track uses the future measurements too
            assert filters[f"{name}_rts"]["mae"][axis] < filters[name]["mae"][axis]


def white_jerk_transition(q: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """F, Q of the 9-state white-jerk model (positions, velocities, accelerations; density q) over dt, by Van
    Loan's method (one matrix exponential of the continuous model), independently of bench_models.white_jerk."""
    A = np.kron(np.diag([1.0, 1.0], 1), np.eye(3))
    GQG = np.kron(np.diag([0.0, 0.0, q]), np.eye(3))
    M = expm(np.block([[-A, GQG], [np.zeros((9, 9)), A.T]]) * dt)
    F = M[9:, 9:].T
    return F, F @ M[:9, 9:]


def batch_map(
    mean0: np.ndarray, cov0: np.ndarray, times: np.ndarray, zs: np.ndarray, H: np.ndarray, R: np.ndarray, q: float
) -> tuple[np.ndarray, np.ndarray]:
    """The linear-Gaussian MAP of the states at ``times`` (K,) given the prior N(mean0, cov0) on the first and
    the measurements zs (K - 1, d) of the others: one weighted least-squares problem over the stacked prior,
    dynamics and measurement residuals (not a recursion). Returns the means (K, n) and marginal covariances."""
    K, n = len(times), len(mean0)
    rows, rhs, covs = [np.eye(n, K * n)], [mean0], [cov0]
    for k in range(K - 1):
        F, Q = white_jerk_transition(q, times[k + 1] - times[k])
        block = np.zeros((n, K * n))
        block[:, k * n : (k + 1) * n], block[:, (k + 1) * n : (k + 2) * n] = -F, np.eye(n)
        rows.append(block), rhs.append(np.zeros(n)), covs.append(Q)
        block = np.zeros((len(zs[k]), K * n))
        block[:, (k + 1) * n : (k + 2) * n] = H
        rows.append(block), rhs.append(zs[k]), covs.append(R)
    A, b, W = np.vstack(rows), np.concatenate(rhs), np.linalg.inv(block_diag(*covs))
    cov = np.linalg.inv(A.T @ W @ A)
    mean = cov @ (A.T @ W @ b)
    return mean.reshape(K, n), np.array([cov[k * n : (k + 1) * n, k * n : (k + 1) * n] for k in range(K)])


def test_the_fixed_lag_smoother_equals_the_batch_map_over_its_window_and_over_the_whole_past():
    """tracker_filters.fixed_lag on grace_velocity's white-jerk filter, fixes at uneven intervals (10-30 s): each
    smoothed estimate it publishes equals E[x_k | every fix up to the newest one it held], computed two ways
    without any RTS recursion: the batch MAP over the window's states (prior: the filter's estimate at the
    window's start) and the batch MAP over every state since the filter's initial prior."""

    labels = ["bx", "by", "bz", "bvx", "bvy", "bvz", "bax", "bay", "baz"]
    cfg = apply_overrides(
        load_scenario("grace_velocity"), ["time.duration=600", "fixed_lag_smoothers.kf_a_lag.lag_s=50"]
    )
    smoother = FixedLagSmoother(cfg, "kf_a_lag")
    q = smoother.dynamics.q
    R, H = 8e-4 * np.eye(3), np.eye(3, 9)
    flt = registry.make_filter("kf", WhiteJerkDynamics(q, labels))
    model = ComponentModel(("bx", "by", "bz")).for_state(labels)
    x0, P0 = np.r_[2.2e5, 0.0, 0.0, np.zeros(6)], np.diag([8e-4] * 3 + [1e2] * 3 + [1.0] * 3)
    flt.initialise(x0, P0, 0.0)
    rng = np.random.default_rng(11)
    times = np.r_[0.0, np.cumsum(rng.choice([10.0, 10.0, 20.0, 30.0], 26))]
    zs, estimates = [], [Estimate(0, 0, "eci", "kf_a", labels, flt.x.copy(), flt.P.copy())]
    for k, t in enumerate(times[1:], start=1):
        z = np.array([2.2e5 + 3.0 * t + 1e-3 * t**2, -1.0 * t, 0.5]) + rng.normal(0.0, 0.03, 3)
        assert flt.process(t, z, R, model).accepted
        zs.append(z)
        estimates.append(Estimate(k, int(round(t * 1e9)), "eci", "kf_a", labels, flt.x.copy(), flt.P.copy()))
    published = []  # (smoothed estimate, index of the newest estimate held)
    for k, e in enumerate(estimates):
        published += [(out, k) for _, out in smoother.on_input("/kf_a/estimate", e)]
    newest_time = times[[k for _, k in published]]
    assert np.all(newest_time - times[[e.step for e, _ in published]] >= 50.0)
    assert [e.step for e, _ in published] == list(range(len(published))) and len(published) >= 18
    zs = np.array(zs)
    for e, newest in published:
        s = e.step
        window_x, window_P = batch_map(estimates[s].x, estimates[s].P, times[s : newest + 1], zs[s:newest], H, R, q)
        past_x, past_P = batch_map(x0, P0, times[: newest + 1], zs[:newest], H, R, q)
        for x, P in ((window_x[0], window_P[0]), (past_x[s], past_P[s])):
            sd = np.sqrt(np.diag(P))
            np.testing.assert_allclose((e.x - x) / sd, 0.0, atol=1e-6)
            np.testing.assert_allclose(e.P / np.outer(sd, sd), P / np.outer(sd, sd), atol=1e-6)
        assert e.t_ns == estimates[s].t_ns and np.all(np.diag(e.P) < np.diag(estimates[s].P) * (1 + 1e-12))
