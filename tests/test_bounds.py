"""The posterior CRB (tracker_filters.pcrb) and the scoring bounds (bench_eval.bounds).

- On a linear-Gaussian model the PCRB is the Kalman filter's covariance (closed form), with process noise
  (TMN eq. 1) and, with none, the batch Fisher information of the scans plus the propagated prior (eq. 2),
  whatever the prior leaves unknown.
- Through the scorer: the registered ``pcrb`` bound of a recorded run equals the covariance of the bench's
  KF on the same linear model, and a bad ``scoring.bounds`` entry is refused before any run.
- On leo_radar, the UKF's Monte Carlo error never beats the bound beyond Monte Carlo tolerance and comes
  close to it (an efficient estimator after the first re-solves).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from bench_engine.config import ScenarioError, load_scenario
from bench_eval import metrics
from bench_eval.bounds import PCRB, BoundSeries, score_bound
from bench_eval.inprocess_runs import bag_data
from bench_eval.report import bound_curves, bounds_table
from bench_eval.scoring import score_bags, scoring_options
from bench_models.isl import RangeAzElModel, RelativePositionModel
from bench_models.relative_dynamics import CWDynamics
from bench_models.truth_dynamics import RelativeOrbitDynamics, truth_dynamics
from orbit_sim import cowell, gravity, relative
from star_tracker.attitude import error_vector, rotation_matrix
from star_tracker.attitude_bound import attitude_information, centroid_jacobians
from tracker_filters.kf import KalmanFilter
from tracker_filters.pcrb import pcrb_along_truth

N_MEAN_MOTION = 2.0 * np.pi / 7200.0


def _cw_truth(steps: int, dt: float) -> tuple[np.ndarray, np.ndarray]:
    dyn = CWDynamics(N_MEAN_MOTION, 0.0)
    x = [np.array([400.0, 500.0, 200.0, 0.1, -0.2, 0.05])]
    for _ in range(steps - 1):
        x.append(dyn.propagate(x[-1], dt))
    return np.arange(steps) * dt, np.array(x)


@pytest.mark.parametrize("sigma_accel", [0.0, 1e-3])
def test_pcrb_equals_the_kalman_covariance_on_a_linear_gaussian_model(sigma_accel):
    """TMN eq. (1) (with Q) and (2) (without) against the bench's KF on CW dynamics and a linear position
    sensor, with scans missing at some steps: the KF's covariance after each step is the bound."""
    dyn = CWDynamics(N_MEAN_MOTION, sigma_accel)
    t, x = _cw_truth(40, 2.0)
    model, R = RelativePositionModel(), np.diag([0.5, 2.0, 1.0]) ** 2
    seen = np.random.default_rng(3).random(len(t)) < 0.7
    seen[0] = True
    P0 = np.diag([50.0, 30.0, 20.0, 1.0, 0.5, 0.2]) ** 2
    kf = KalmanFilter(dyn)
    kf.initialise(x[0], P0, t[0])
    expected = [P0]
    for k in range(1, len(t)):
        if seen[k]:
            kf.process(t[k], model.h(x[k]), R, model)
        else:
            kf.predict(t[k])
        expected.append(kf.P.copy())
    bound = pcrb_along_truth(dyn, t, x, [[(model, R)] if s else [] for s in seen], np.linalg.inv(P0))
    np.testing.assert_allclose(bound, np.array(expected), rtol=1e-7, atol=1e-12)


def test_pcrb_without_process_noise_is_the_batch_information_of_the_scans_plus_the_prior():
    """Zero process noise and a prior that leaves the velocity unknown (singular J_0): J_k is
    Phi_k^{-T} J_0 Phi_k^{-1} + sum_i Phi(t_i, t_k)^T H^T R^{-1} H Phi(t_i, t_k) (TMN eq. 2 unrolled); the bound
    is NaN while the state is unobservable (one scan of position only)."""
    dyn = CWDynamics(N_MEAN_MOTION, 0.0)
    t, x = _cw_truth(12, 5.0)
    model, R = RelativePositionModel(), np.diag([0.3, 0.3, 0.6]) ** 2
    J0 = np.diag([1 / 10.0**2] * 3 + [0.0] * 3)
    bound = pcrb_along_truth(dyn, t, x, [[(model, R)]] * len(t), J0)
    assert np.all(np.isnan(bound[0]))
    H = model.jacobian(x[0])
    info = H.T @ np.linalg.inv(R) @ H
    for k in range(1, len(t)):
        Phi_k = dyn.transition_matrix(x[0], t[k] - t[0])
        back = [np.linalg.inv(Phi_k) @ dyn.transition_matrix(x[0], t[i] - t[0]) for i in range(1, k + 1)]
        Jk = np.linalg.inv(Phi_k).T @ J0 @ np.linalg.inv(Phi_k) + sum(B.T @ info @ B for B in back)
        np.testing.assert_allclose(bound[k], np.linalg.inv(Jk), rtol=1e-6, atol=1e-12)


def _linear_formation(tmp_sigma: float = 1e-3) -> dict:
    """formation_pf's CW truth measured by a linear position sensor with misses, tracked by the bench's KF
    with the bound's own model (CW with white accelerations): the KF is then the bound."""
    sensor = "sensors.radio={type: relative_position, interval: 1.0, sigma_position: 0.5, p_detect: 0.8}"
    dyn = f"{{model: cw, sigma_accel: {tmp_sigma}}}"
    return load_scenario(
        "formation_pf",
        [
            sensor,
            "time.duration=60.0",
            f"filter_defaults.dynamics={dyn}",
            "filters={kf: {type: kf}}",
            "estimators=[kf]",
            f"scoring.bounds={{pcrb: {{bound: pcrb, params: {{dynamics: {dyn}, prior: kf}}, from_s: 10.0}}}}",
        ],
    )


def test_the_registered_pcrb_of_a_recorded_run_is_the_kalman_covariance_on_a_linear_model():
    cfg = _linear_formation()
    data = bag_data(cfg, ["kf"], seed=5)
    est = data.estimates["kf"]
    bound = PCRB.run(data, scoring_options(cfg).bounds["pcrb"].params)
    assert list(bound.steps) == list(est.steps) and len(est.steps) < 61  # misses: scans only
    np.testing.assert_allclose(bound.P, est.P, rtol=1e-7, atol=1e-12)
    result, series = score_bags([data], with_series=True)
    scored = result["estimators"]["kf"]["bounds"]["pcrb"]
    sigma = np.sqrt(np.mean(np.trace(est.P[:, :3, :3], axis1=1, axis2=2)[est.t - est.t[0] >= 10.0]))
    assert scored["position"]["sqrt_bound"] == pytest.approx(sigma, rel=1e-9)
    assert set(scored["axes"]) == {"x", "y", "z", "vx", "vy", "vz"}
    # the report's generic pieces: the dashed curve is sqrt(trace) of the KF's own covariance, one table row a group
    [(name, t, curve)] = bound_curves(series, "position")
    np.testing.assert_allclose(curve, np.sqrt(np.trace(est.P[:, :3, :3], axis1=1, axis2=2)), rtol=1e-9)
    assert [row[:3] for row in bounds_table(result["estimators"]).rows] == [
        ["kf", "pcrb", "position [m]"],
        ["kf", "pcrb", "velocity [m/s]"],
    ]


@pytest.mark.parametrize(
    "entry, message",
    [
        ("{pcrb: {bound: pcrb, params: {dynamics: {model: cw, sigma_accel: 0.0}}, form_s: 1.0}}", "form_s"),
        ("{pcrb: {bound: nope, params: {}}}", "bound"),
        ("{pcrb: {bound: pcrb, params: {dynamics: {model: cw, sigma_accel: 0.0}, prior: nobody}}}", "nobody"),
        ("{pcrb: {bound: pcrb, params: {prior: pf}}}", "dynamics"),
    ],
)
def test_a_bad_bounds_entry_is_refused_before_any_run(entry, message):
    with pytest.raises(ScenarioError, match=message):
        scoring_options(load_scenario("formation_pf", [f"scoring.bounds={entry}"]))


def test_efficiency_is_one_when_the_error_is_the_bound_and_nan_steps_are_left_out():
    """score_bound's summaries on synthetic tracks: errors whose per-step RMS over runs is exactly the bound's
    square root give efficiency 1; steps where the bound is not finite yet are not summarised."""
    t = np.arange(5.0)
    P = np.stack([np.eye(6) * s for s in (np.nan, 4.0, 4.0, 1.0, 1.0)])
    err = np.array([0.0, 2.0, 2.0, 1.0, 1.0])[:, None] * np.ones((1, 6))
    tracks = [
        metrics.Track(
            t,
            np.zeros((5, 6)) + sign * err,
            np.tile(np.eye(6), (5, 1, 1)),
            np.zeros((5, 6)),
            ["x", "y", "z", "vx", "vy", "vz"],
        )
        for sign in (1.0, -1.0)
    ]
    bound = BoundSeries(np.arange(5), t, ["x", "y", "z", "vx", "vy", "vz"], P)
    scores, series = score_bound(tracks, [bound, bound], from_s=0.0, t0=0.0)
    assert scores["position"]["efficiency"] == pytest.approx(1.0)
    assert scores["axes"]["vz"]["final_sqrt_bound"] == pytest.approx(1.0)
    assert np.isnan(series["position"][0]) and series["position"][1] == pytest.approx(np.sqrt(12.0))


def test_leo_radar_ukf_error_is_above_the_pcrb_within_monte_carlo_tolerance_and_near_it():
    """4 in-process runs of the default UKF (Gauss-Newton re-solves over every scan: efficient once they
    start). At 150, 250 and 400 s after the first scan, sum over runs of e^T J e (J the PCRB information) would
    be chi-square with 6N dof for an efficient, unbiased Gaussian estimator: it is above the 0.1 % quantile (no
    estimator beats the bound) and below the 99.9 % one (the UKF is consistent with efficiency 1)."""
    cfg = load_scenario(
        "leo_radar",
        ["scoring.bounds={pcrb: {bound: pcrb, params: {dynamics: {model: orbit_j2, sigma_accel: 0.0}, prior: ukf}}}"],
    )
    params = scoring_options(cfg).bounds["pcrb"].params
    runs = [bag_data(cfg, ["ukf"], seed) for seed in range(4)]
    bounds = [PCRB.run(data, params) for data in runs]
    for after in (150.0, 250.0, 400.0):
        total = 0.0
        for data, bound in zip(runs, bounds):
            est = data.estimates["ukf"]
            k = int(np.searchsorted(est.t, est.t[0] + after))
            j = int(np.searchsorted(bound.steps, est.steps[k]))
            e = est.x[k] - data.truth[int(est.steps[k])][1]
            total += float(e @ np.linalg.solve(bound.P[j], e))
        dof = 6 * len(runs)
        assert chi2.ppf(0.001, dof) <= total <= chi2.ppf(0.999, dof), (after, total / dof)


def test_formation_truth_transition_matrices_match_finite_differences_of_the_truth():
    """bench_models.truth_dynamics.RelativeOrbitDynamics (formation_j2: chief and deputy on two-body + J2): the
    product of its step matrices F_k equals central differences of the truth's relative state (both orbits
    integrated by orbit_sim.cowell, mapped to LVLH by orbit_sim.relative) with respect to the initial one."""
    cfg = load_scenario("formation_cqkf", ["truth.chief.e=0.005"])
    dyn = truth_dynamics(cfg)
    assert isinstance(dyn, RelativeOrbitDynamics)
    mu, j2, re = dyn.mu, dyn.j2, dyn.re
    times = np.array([300.0, 310.0, 330.0, 900.0, 2000.0])
    chief = cowell.propagate(dyn.chief0, np.concatenate(([0.0], times)), mu, j2, re)[1:]
    accel = gravity.acceleration(chief[:, :3], mu, j2, re)

    def relative_states(rel0: np.ndarray) -> np.ndarray:
        deputy0 = relative.lvlh_to_eci(chief[0], rel0, accel[0])
        return relative.eci_to_lvlh(chief, cowell.propagate(deputy0, times, mu, j2, re), accel)

    states = relative_states(np.array([120.0, 480.0, -250.0, 0.05, -0.2, 0.3]))
    F = dyn.transition_matrices(times, states)
    steps = np.array([20.0] * 3 + [0.02] * 3)  # big: the integrator's ~7e-6 m error / (2 step) small
    fd = np.stack(
        [
            (relative_states(states[0] + d) - relative_states(states[0] - d)) / (2 * d[i])
            for i, d in enumerate(np.diag(steps))
        ],
        axis=-1,
    )  # (K, 6, 6): d x_k / d x_0
    Phi = np.eye(6)
    for k, Fk in enumerate(F, start=1):
        Phi = Fk @ Phi
        np.testing.assert_allclose(Phi * steps, fd[k] * steps, atol=1e-7 * np.max(np.abs(fd[k] * steps)))


@pytest.mark.parametrize("convention", ["radial_along_normal", "along_radial"])
def test_isl_jacobian_series_is_the_jacobian_of_each_state_and_matches_finite_differences(convention):
    """RangeAzElModel.jacobian_series (the PCRB's vectorised scan information) row by row against ``jacobian``
    and against central differences of ``h`` (azimuth away from its 0 / 2 pi cut)."""
    model = RangeAzElModel(convention)
    x = np.random.default_rng(7).normal(0.0, 500.0, (20, 9))
    x = x[np.abs(np.sin(model.h(x)[:, 1])) > 0.1]
    H = model.jacobian_series(x, np.zeros(len(x)))
    np.testing.assert_allclose(H, [model.jacobian(xk) for xk in x], rtol=1e-12, atol=1e-15)
    step = 1e-3
    fd = np.stack([(model.h(x + step * e) - model.h(x - step * e)) / (2 * step) for e in np.eye(9)], axis=-1)
    np.testing.assert_allclose(H, fd, rtol=1e-6, atol=1e-9)


def test_star_frame_attitude_information_matches_finite_differences_and_quest_near_the_boresight():
    """star_tracker.attitude_bound: H_i = d t_i / d dtheta against central differences of the tangent-plane
    positions of stars seen by A' = exp(-[dtheta x]) A (attitude.py's error convention, checked with
    error_vector), and J against the QUEST measurement model's sum (I - b b^T) / sigma^2 for stars near the
    boresight."""
    rng = np.random.default_rng(11)
    A = rotation_matrix(rng.normal(size=3))
    b = np.column_stack([rng.uniform(-0.15, 0.15, (12, 2)), np.ones(12)])
    r = (b / np.linalg.norm(b, axis=1, keepdims=True)) @ A  # ICRS directions: b = A r

    def tangent(A_: np.ndarray) -> np.ndarray:
        v = r @ A_.T
        return v[:, :2] / v[:, 2:]

    step, fd = 1e-6, []
    for e in np.eye(3):
        plus, minus = rotation_matrix(-step * e) @ A, rotation_matrix(step * e) @ A
        np.testing.assert_allclose(error_vector(plus, A), step * e, atol=1e-15)
        fd.append((tangent(plus) - tangent(minus)) / (2 * step))
    np.testing.assert_allclose(centroid_jacobians(tangent(A)), np.stack(fd, axis=-1), rtol=1e-6, atol=1e-9)
    near = b[:, :2] * 0.01
    u = np.column_stack([near, np.ones(len(near))])
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    quest = sum(np.eye(3) - np.outer(v, v) for v in u) / 1e-4**2
    np.testing.assert_allclose(attitude_information(near, 1e-4), quest, atol=1e-5 * np.abs(quest).max())
