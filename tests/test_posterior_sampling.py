"""The importance-sampled reference posterior (tracker_filters/posterior_sampling.py).

Known answers: on a linear-Gaussian deterministic problem the posterior is Gaussian and the Kalman filter's
estimate is exact, so the sampler must reproduce it within Monte Carlo error; on the leo_radar problem its
cost is the batch's Gauss-Newton cost at the same x0 (no linearisation enters either).
"""

import numpy as np
import pytest

from bench_engine.config import load_scenario
from bench_engine.inprocess import run_in_process
from bench_models.linear_models import ConstantVelocity, PositionMeasurement
from orbit_sim.truth import build_truth
from radar_sensor.sensor import build_sensor
from tracker_filters.builders import build_filter_stack
from tracker_filters.kf import KalmanFilter
from tracker_filters.posterior_sampling import adaptive_posterior, batch_cost, weighted_moments
from tracker_filters.relinearisation import PassBatch


def linear_problem(seed: int = 3):
    dyn, meas = ConstantVelocity(sigma_accel=0.0, ndim=2), PositionMeasurement(ndim=2)
    rng = np.random.default_rng(seed)
    x_true = np.array([0.0, 0.0, 3.0, -1.0])
    m0, P0 = x_true + rng.normal(0.0, [5.0, 5.0, 2.0, 2.0]), np.diag([25.0, 25.0, 4.0, 4.0])
    R = np.diag([4.0, 9.0])
    batch, kf = PassBatch(dyn, m0, P0, 0.0), KalmanFilter(dyn)
    kf.initialise(m0, P0, 0.0)
    for k in range(1, 8):
        t = 0.5 * k
        z = dyn.propagate(x_true, t)[0:2] + rng.multivariate_normal(np.zeros(2), R)
        batch.add(t, z, R, meas)
        kf.process(t, z, R, meas)
    return batch, kf


def test_on_a_linear_gaussian_problem_the_sampled_posterior_is_the_kalman_filters():
    batch, kf = linear_problem()
    post = adaptive_posterior(batch, batch.m0, n_samples=20_000, iterations=3, rng=np.random.default_rng(0))
    assert post.ess > 3_000  # ~22 % efficiency: a t5 proposal twice as wide as a Gaussian target, in 4-D
    err = post.mean - kf.x
    assert err @ np.linalg.solve(kf.P, err) < 25.0 / post.ess * 4  # mean within MC error (chi2(4)/ESS)
    ratio = np.linalg.eigvalsh(np.linalg.solve(kf.P, post.covariance))
    assert np.all(np.abs(ratio - 1.0) < 0.1), ratio


def test_weighted_moments_of_equal_weights_are_the_sample_moments():
    X = np.random.default_rng(1).normal(size=(50, 3))
    mean, cov = weighted_moments(X, np.full(50, 1.0 / 50))
    assert np.allclose(mean, X.mean(axis=0))
    assert np.allclose(cov, np.cov(X.T, bias=True))


def test_the_sampled_cost_is_the_batch_cost_on_the_radar_problem():
    cfg = load_scenario("leo_radar", ["time.duration=3", "sensors.radar.p_detect=1.0"])
    run = run_in_process(cfg, ["ukf"], seed=2)
    truth, sensor, stack = build_truth(cfg), build_sensor(cfg, "radar"), build_filter_stack(cfg, "ukf")
    first, *scans = run.items["/radar/measurement"]
    batch = PassBatch(stack.filter.dynamics, *stack.initialise(first.z, first.R, sensor, first.t), first.t)
    for m in scans:
        batch.add(m.t, m.z, m.R, sensor.model)
    X0 = truth.states[0] + np.random.default_rng(4).normal(0.0, [2e3, 2e3, 2e3, 50.0, 50.0, 50.0], (4, 6))
    cost, X_last = batch_cost(batch, X0)
    for x0, c, x_last in zip(X0, cost, X_last):
        lin = batch.linearise(x0)
        assert c == pytest.approx(lin.cost, rel=1e-6)
        assert np.allclose(x_last, lin.x_last, atol=1e-3)


def test_too_few_samples_are_refused():
    batch, _ = linear_problem()
    with pytest.raises(ValueError, match="n_samples >= 40"):
        adaptive_posterior(batch, batch.m0, n_samples=20, iterations=1, rng=np.random.default_rng(0))
