"""Cubature-quadrature rule (paper 004 set-up) and the CQKF (paper 004 eqs. 14-27)."""

import numpy as np
import pytest
from scipy.special import chdtri, gamma

from bench_engine.config import load_scenario
from bench_eval.inprocess_runs import bag_data
from bench_eval.metrics import nees_summary
from bench_eval.scoring import track_of
from bench_models.isl import RelativePositionModel
from bench_models.linear_models import ConstantVelocity, PositionMeasurement
from bench_models.relative_dynamics import CWBiasDynamics
from orbit_sim.angles import wrapped_residual
from tracker_filters.cqkf import CubatureQuadratureKF, weighted_measurement_mean
from tracker_filters.cubature import cubature_quadrature_points, radial_rule
from tracker_filters.kf import KalmanFilter


def random_gaussian(n, seed):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    return rng.normal(size=n), A @ A.T + 0.5 * np.eye(n)


@pytest.mark.parametrize("n", [1, 2, 3, 6, 9])
@pytest.mark.parametrize("order", [1, 2, 3])
def test_rule_shape_and_positive_weights(n, order):
    xi, w = cubature_quadrature_points(n, order)
    assert xi.shape == (2 * n * order, n) and w.shape == (2 * n * order,)
    assert np.all(w > 0) and w.sum() == pytest.approx(1.0, abs=1e-13)


@pytest.mark.parametrize("n", [1, 2, 3, 6, 9])
@pytest.mark.parametrize("order", [1, 2, 3])
def test_polynomials_up_to_degree_3_are_exact_for_any_gaussian(n, order):
    m, P = random_gaussian(n, seed=10 * n + order)
    xi, w = cubature_quadrature_points(n, order)
    X = m + xi @ np.linalg.cholesky(P).T
    second = np.einsum("k,ki,kj->ij", w, X, X)
    third = np.einsum("k,ki,kj,kl->ijl", w, X, X, X)
    exact_third = (
        np.einsum("i,j,l->ijl", m, m, m)
        + np.einsum("i,jl->ijl", m, P)
        + np.einsum("j,il->ijl", m, P)
        + np.einsum("l,ij->ijl", m, P)
    )
    assert np.allclose(w @ X, m, atol=1e-12)
    assert np.allclose(second, P + np.outer(m, m), atol=1e-11)
    assert np.allclose(third, exact_third, atol=1e-10)


@pytest.mark.parametrize("n", [1, 3, 6, 9])
@pytest.mark.parametrize("order", [1, 2, 3, 4])
def test_radial_rule_moments(n, order):
    """Generalized Gauss-Laguerre: sum A_i lam_i^k = Gamma(alpha + k + 1) exactly for k <= 2n' - 1 only."""
    alpha = n / 2 - 1
    lam, A = radial_rule(n, order)
    for k in range(2 * order):
        assert A @ lam**k == pytest.approx(gamma(alpha + k + 1), rel=1e-10)
    k = 2 * order
    assert abs(A @ lam**k / gamma(alpha + k + 1) - 1.0) > 1e-3


@pytest.mark.parametrize("n", [2, 4, 6, 9])
def test_fourth_radial_moment_needs_order_two(n):
    """E|x|^4 = n(n + 2): the CKF (n' = 1) gives n^2, n' >= 2 is exact."""
    for order, exact in ((1, False), (2, True), (3, True)):
        xi, w = cubature_quadrature_points(n, order)
        value = w @ np.sum(xi**2, axis=1) ** 2
        assert bool(value == pytest.approx(n * (n + 2), rel=1e-10)) is exact


def test_order_one_is_the_standard_cubature_rule():
    n = 5
    xi, w = cubature_quadrature_points(n, 1)
    expected = np.sqrt(n) * np.vstack([np.eye(n), -np.eye(n)])
    assert np.allclose(xi, expected, atol=1e-12) and np.allclose(w, 1 / (2 * n))


@pytest.mark.parametrize("order", [0, -1, 1.5])
def test_invalid_order_raises(order):
    with pytest.raises(ValueError):
        CubatureQuadratureKF(ConstantVelocity(0.1, ndim=2), order=order)


class RangeAndProduct:
    """Nonlinear, angle-free 2-D measurement [|r|, x y / 100] on the state [x, y, vx, vy]."""

    labels = ("range", "product")
    angle_indices = ()

    def h(self, x, t):
        x = np.asarray(x, dtype=float)
        return np.stack([np.hypot(x[..., 0], x[..., 1]), x[..., 0] * x[..., 1] / 100.0], axis=-1)

    def jacobian(self, x, t):
        r = np.hypot(x[0], x[1])
        return np.array([[x[0] / r, x[1] / r, 0, 0], [x[1] / 100, x[0] / 100, 0, 0]])

    def residual(self, z, z_pred):
        return np.asarray(z, dtype=float) - np.asarray(z_pred, dtype=float)


class RangeBearing:
    """[|r|, atan2(y, x)] on the state [x, y, vx, vy]; the bearing is an angle."""

    labels = ("range", "bearing")
    angle_indices = (1,)

    def h(self, x, t):
        x = np.asarray(x, dtype=float)
        return np.stack([np.hypot(x[..., 0], x[..., 1]), np.arctan2(x[..., 1], x[..., 0])], axis=-1)

    def jacobian(self, x, t):
        r2 = x[0] ** 2 + x[1] ** 2
        r = np.sqrt(r2)
        return np.array([[x[0] / r, x[1] / r, 0, 0], [-x[1] / r2, x[0] / r2, 0, 0]])

    def residual(self, z, z_pred):
        return wrapped_residual(z, z_pred, self.angle_indices)


def direct_ckf_step(x, P, dt, z, R, dynamics, model):
    """Arasaratnam & Haykin's CKF coded from scratch: points x +/- sqrt(n) columns of chol(P), weights 1/(2n)."""
    n = x.size

    def points(m, C):
        L = np.linalg.cholesky(C)
        return np.vstack([m + np.sqrt(n) * L.T, m - np.sqrt(n) * L.T])

    X = dynamics.propagate(points(x, P), dt)
    x = X.mean(axis=0)
    P = (X - x).T @ (X - x) / (2 * n) + dynamics.process_noise(x, dt)
    X = points(x, P)
    Y = model.h(X, 0.0)
    y = Y.mean(axis=0)
    Pyy = (Y - y).T @ (Y - y) / (2 * n) + R
    Pxy = (X - x).T @ (Y - y) / (2 * n)
    K = Pxy @ np.linalg.inv(Pyy)
    nu = z - y
    return x + K @ nu, P - K @ Pyy @ K.T, float(nu @ np.linalg.solve(Pyy, nu))


def simulate(model, steps, seed, R):
    rng = np.random.default_rng(seed)
    truth = np.array([300.0, 150.0, -2.0, 3.0])
    zs = []
    for _ in range(steps):
        truth = truth + np.array([truth[2], truth[3], 0, 0])
        zs.append(model.h(truth, 0.0) + rng.multivariate_normal(np.zeros(len(R)), R))
    return zs


def test_order_one_equals_a_directly_coded_ckf():
    dynamics = ConstantVelocity(0.05, ndim=2)
    model = RangeAndProduct()
    R = np.diag([0.5**2, 2.0**2])
    x0, P0 = np.array([290.0, 160.0, 0.0, 0.0]), np.diag([20.0**2, 20.0**2, 3.0**2, 3.0**2])
    f = CubatureQuadratureKF(dynamics, order=1)
    f.initialise(x0, P0, 0.0)
    x, P = x0.copy(), P0.copy()
    for k, z in enumerate(simulate(model, 15, seed=3, R=R), start=1):
        step = f.process(float(k), z, R, model)
        x, P, nis = direct_ckf_step(x, P, 1.0, z, R, dynamics, model)
        assert step.accepted and step.nis == pytest.approx(nis, rel=1e-9)
        assert np.allclose(f.x, x, rtol=1e-10, atol=1e-9)
        assert np.allclose(f.P, P, rtol=1e-8, atol=1e-10)


def test_order_two_differs_from_the_ckf_on_a_nonlinear_model():
    dynamics = ConstantVelocity(0.05, ndim=2)
    model = RangeAndProduct()
    R = np.diag([0.5**2, 2.0**2])
    x0, P0 = np.array([290.0, 160.0, 0.0, 0.0]), np.diag([20.0**2, 20.0**2, 3.0**2, 3.0**2])
    filters = [CubatureQuadratureKF(dynamics, order=o) for o in (1, 2)]
    for f in filters:
        f.initialise(x0, P0, 0.0)
    for k, z in enumerate(simulate(model, 3, seed=3, R=R), start=1):
        for f in filters:
            f.process(float(k), z, R, model)
    assert not np.allclose(filters[0].x, filters[1].x, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("order", [1, 2, 3])
def test_equals_the_kalman_filter_on_a_linear_model(order):
    dynamics, model = ConstantVelocity(0.2, ndim=3), PositionMeasurement(ndim=3)
    rng = np.random.default_rng(11)
    R = np.diag([4.0, 9.0, 1.0])
    x0 = np.array([10.0, -5.0, 3.0, 1.0, 0.5, -0.2])
    P0 = np.diag([100.0, 100.0, 100.0, 4.0, 4.0, 4.0])
    cqkf, kf = CubatureQuadratureKF(dynamics, order=order), KalmanFilter(dynamics)
    for f in (cqkf, kf):
        f.initialise(x0, P0, 0.0)
    truth = x0 + rng.normal(size=6) * np.sqrt(np.diag(P0))
    for k in range(1, 21):
        truth = dynamics.propagate(truth, 1.0)
        z = model.h(truth, 0.0) + rng.normal(size=3) * np.sqrt(np.diag(R))
        s1, s2 = cqkf.process(float(k), z, R, model), kf.process(float(k), z, R, model)
        assert s1.nis == pytest.approx(s2.nis, rel=1e-8)
        assert np.allclose(cqkf.x, kf.x, rtol=1e-10, atol=1e-9)
        assert np.allclose(cqkf.P, kf.P, rtol=1e-8, atol=1e-10)


def test_equals_the_kalman_filter_on_the_9_state_cw_bias_model():
    dynamics = CWBiasDynamics(2 * np.pi / 5952.8, sigma_accel=1e-3, sigma_bias=1e-6)
    model = RelativePositionModel()
    R = 1e-3 * np.eye(3)
    x0 = np.array([100.0, 200.0, -50.0, 0.1, -0.2, 0.05, 0.0, 0.0, 0.0])
    P0 = np.diag([4.0] * 3 + [1e-2] * 3 + [1e-8] * 3)
    cqkf, kf = CubatureQuadratureKF(dynamics, order=2), KalmanFilter(dynamics)
    for f in (cqkf, kf):
        f.initialise(x0, P0, 0.0)
    rng = np.random.default_rng(12)
    truth = x0 + rng.normal(size=9) * np.sqrt(np.diag(P0))
    for k in range(1, 31):
        truth = dynamics.propagate(truth, 1.0)
        z = model.h(truth) + rng.normal(size=3) * np.sqrt(np.diag(R))
        s1, s2 = cqkf.process(float(k), z, R, model), kf.process(float(k), z, R, model)
        assert s1.nis == pytest.approx(s2.nis, rel=1e-7)
    assert np.allclose(cqkf.x, kf.x, rtol=1e-9, atol=1e-9)
    assert np.allclose(cqkf.P, kf.P, rtol=1e-6, atol=1e-14)


def test_circular_mean_of_angles_straddling_pi():
    Y = np.array([[1.0, np.pi - 0.1], [3.0, -np.pi + 0.1]])
    y = weighted_measurement_mean(Y, np.array([0.5, 0.5]), [1])
    assert y[0] == pytest.approx(2.0)
    assert abs(wrapped_residual(y[1:], np.array([np.pi]), [0])[0]) < 1e-12


def rotate(v, angle):
    c, s = np.cos(angle), np.sin(angle)
    Rm = np.array([[c, -s], [s, c]])
    return np.concatenate([Rm @ v[:2], Rm @ v[2:]])


@pytest.mark.parametrize("order", [1, 2])
def test_bearing_across_the_wrap_matches_the_rotated_problem(order):
    """A target crossing bearing +/-pi is filtered like the same geometry rotated by 90 degrees.

    Not bit-identical: the points follow Cholesky columns, which do not rotate with the covariance, so the
    two runs differ at the level of the rule's third-order error (~1e-5 here); a wrap error would be 2 pi.
    """
    dynamics, model = ConstantVelocity(0.05, ndim=2), RangeBearing()
    R = np.diag([1.0, np.radians(0.5) ** 2])
    x0 = np.array([-500.0, 20.0, 0.0, -4.0])
    P0 = np.diag([30.0**2, 30.0**2, 2.0**2, 2.0**2])
    rng = np.random.default_rng(5)
    turn = -np.pi / 2
    wrapped, rotated = CubatureQuadratureKF(dynamics, order), CubatureQuadratureKF(dynamics, order)
    wrapped.initialise(x0, P0, 0.0)
    rotated.initialise(rotate(x0, turn), P0, 0.0)
    truth = np.array([-505.0, 25.0, 0.0, -4.5])
    for k in range(1, 16):
        truth = dynamics.propagate(truth, 1.0)
        z = model.h(truth, 0.0) + rng.normal(size=2) * np.sqrt(np.diag(R))
        z_rot = np.array([z[0], z[1] + turn])
        a, b = wrapped.process(float(k), z, R, model), rotated.process(float(k), z_rot, R, model)
        assert a.nis == pytest.approx(b.nis, rel=1e-3) and a.nis < 30.0
        assert np.allclose(rotate(wrapped.x, turn), rotated.x, atol=1e-3)
    assert np.all(np.abs(wrapped.x[:2] - truth[:2]) < 5.0)


def test_the_cqkf_is_consistent_on_formation_cqkf_nonlinear_scenario():
    """formation_cqkf as configured (J2 truth of both spacecraft, range/angles every 1 s, one orbit; the CQKF
    n' = 2 with the Schweighart-Sedwick model and the scenario's sigma), three seeded runs in process
    (bench_engine.inprocess, no ROS), scored by the bench's own NEES code (bench_eval.metrics.nees_summary on
    the scorer's tracks): the time-averaged NEES of position and velocity lies in the 95 % chi-square band of
    the three-run average, chi2(6 N) / N (the rule the scenario's sigma was chosen by; the sweep measured 6.6).
    A covariance 4x too large (NEES / 4) or too small (x 4) falls outside it."""

    cfg = load_scenario("formation_cqkf")
    tracks = [track_of(bag_data(cfg, ["ss"], seed), "ss") for seed in (1, 2, 3)]
    assert tracks[0].labels == ["x", "y", "z", "vx", "vy", "vz"] and tracks[0].t[-1] > 5900.0
    summary = nees_summary(tracks)
    lo, hi = summary["bounds"]
    np.testing.assert_allclose([lo, hi], chdtri(18, [0.975, 0.025]) / 3, rtol=1e-12)
    assert lo < summary["mean"] < hi, f"NEES {summary['mean']:.2f} outside [{lo:.2f}, {hi:.2f}]"
    assert 4.0 * summary["mean"] > hi and summary["mean"] / 4.0 < lo  # the band tells a factor 4 apart
    assert summary["fraction_inside"] > 0.7
