"""KF / EKF / UKF, the orbit and linear models they run on, and the filter registry."""

import numpy as np
import pytest
from scipy.integrate import trapezoid
from scipy.optimize import least_squares
from scipy.stats import chi2

from bench_models.linear_models import ConstantVelocity, PositionMeasurement
from bench_models.orbit_dynamics import OrbitJ2Dynamics
from bench_models.radar import GroundRadarModel
from orbit_sim.cowell import propagate
from orbit_sim.frames import ecef_to_eci, enu_rotation
from orbit_sim.kepler import kepler_to_cartesian
from tracker_filters.ekf import ExtendedKalmanFilter, SecondOrderEKF, second_order_moments
from tracker_filters.initialisation import initial_state_from_scan
from tracker_filters.kf import KalmanFilter
from tracker_filters.registry import filter_names, make_filter
from tracker_filters.relinearisation import PassBatch
from tracker_filters.sigma_points import ScaledSigmaPoints
from tracker_filters.ukf import UnscentedKalmanFilter

CHAMP = kepler_to_cartesian(
    6739137.0, 0.00033, np.radians(87.2346), np.radians(303.3713), np.radians(81.5653), np.radians(80.0)
)
STATION = (np.radians(78.15306), np.radians(16.02889), 445.0)
R_RADAR = np.diag([1000.0, 0.017**2, 0.017**2])


# ----------------------------------------------------------------------------------------- models


@pytest.mark.parametrize("dt", [0.1, -0.1, 10.0, 60.0, 300.0])
def test_orbit_transition_matrix_matches_finite_differences_of_propagate(dt):
    dyn = OrbitJ2Dynamics(sigma_accel=0.0)
    Phi = dyn.transition_matrix(CHAMP, dt)
    steps = np.array([100.0, 100.0, 100.0, 1.0, 1.0, 1.0])
    Phi_fd = np.column_stack(
        [
            (dyn.propagate(CHAMP + s * e, dt) - dyn.propagate(CHAMP - s * e, dt)) / (2 * s)
            for s, e in zip(steps, np.eye(6))
        ]
    )
    # The gravity-gradient part of each 3x3 block (Phi minus the force-free [[I, dt I], [0, I]]): the
    # midpoint-frozen G leaves a second-order ~(h |dG/dt| / |G|)^2 (~2e-4 at h = 10 s) of it in d r / d v
    # and d v / d r, and a first-order ~h |dG/dt| / 6 |G| (3e-3) in d r / d r and d v / d v.
    free = np.eye(6)
    free[0:3, 3:6] = dt * np.eye(3)
    tolerance = {(0, 0): 1e-2, (0, 3): 1e-3, (3, 0): 1e-3, (3, 3): 1e-2}
    for (r, c), tol in tolerance.items():
        error = np.abs(Phi - Phi_fd)[r : r + 3, c : c + 3].max()
        fd_noise = 1e-8  # rounding of 7e6 m positions over the 1 m/s velocity steps
        assert error <= tol * np.abs(Phi_fd - free)[r : r + 3, c : c + 3].max() + fd_noise, (r, c)
    assert np.abs(Phi - Phi_fd).max() < 2e-5 * np.abs(Phi_fd).max()


def test_orbit_propagate_single_and_batch_agree_and_process_noise_is_white_acceleration():
    dyn = OrbitJ2Dynamics(sigma_accel=0.5)
    X = CHAMP + np.diag([1e3, -1e3, 2e3, 1.0, -1.0, 2.0])
    batch = dyn.propagate(X, 25.0)
    np.testing.assert_allclose(batch, np.array([dyn.propagate(x, 25.0) for x in X]), rtol=1e-12)
    Q = dyn.process_noise(CHAMP, 2.0)
    q = 0.25
    np.testing.assert_allclose(Q[0:3, 0:3], np.eye(3) * q * 8.0 / 3.0)
    np.testing.assert_allclose(Q[0:3, 3:6], np.eye(3) * q * 2.0)
    np.testing.assert_allclose(Q[3:6, 3:6], np.eye(3) * q * 2.0)
    np.testing.assert_allclose(Q, Q.T)
    assert np.all(np.linalg.eigvalsh(Q) > 0.0)
    assert not Q.flags.writeable
    dyn.sigma_accel = 1.0
    np.testing.assert_allclose(dyn.process_noise(CHAMP, 2.0), Q / q)
    with pytest.raises(ValueError, match="sigma_accel"):
        OrbitJ2Dynamics(sigma_accel=-1.0)


def test_constant_velocity_model_is_the_exact_discretisation():
    cv = ConstantVelocity(sigma_accel=2.0, ndim=2)
    assert tuple(cv.labels) == ("x", "y", "vx", "vy")
    x = np.array([1.0, 2.0, 3.0, -4.0])
    np.testing.assert_allclose(cv.propagate(x, 0.5), [2.5, 0.0, 3.0, -4.0])
    np.testing.assert_allclose(cv.propagate(np.vstack((x, 2 * x)), 0.5)[1], 2 * cv.propagate(x, 0.5))
    # Q = integral of F(s) G q G^T F(s)^T ds over the step (Van Loan), here by quadrature.
    dt, s = 0.7, np.linspace(0.0, 0.7, 20001)
    integrand = np.array([[[si * si, si], [si, 1.0]] for si in s]) * 4.0
    expected = trapezoid(integrand, s, axis=0)
    Q = cv.process_noise(x, dt)
    np.testing.assert_allclose(Q[np.ix_([0, 2], [0, 2])], expected, rtol=1e-6)
    h = PositionMeasurement(ndim=2)
    np.testing.assert_allclose(h.h(x, 0.0), [1.0, 2.0])
    np.testing.assert_allclose(h.jacobian(x, 0.0), np.eye(2, 4))


# --------------------------------------------------------------------------------- sigma points


def test_sigma_points_reproduce_mean_and_covariance():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(6, 6))
    P = A @ A.T + np.eye(6)
    x = rng.normal(size=6) * 1e6
    for alpha in (1e-3, 0.3, 1.0):
        pts = ScaledSigmaPoints(6, alpha)
        X = pts.generate(x, P)
        assert X.shape == (13, 6)
        assert pts.wm.sum() == pytest.approx(1.0)
        np.testing.assert_allclose(pts.mean(X), x, rtol=1e-12)
        np.testing.assert_allclose(pts.covariance(X - x), P, rtol=1e-6, atol=1e-9 * np.abs(P).max())
    with pytest.raises(ValueError, match=r"alpha must be in \(0, 1\]"):
        ScaledSigmaPoints(6, 0.0)


def test_angle_mean_has_no_wrap_artefact():
    model = GroundRadarModel(*STATION)
    pts = ScaledSigmaPoints(3, 1.0)
    offsets = np.array([0.0, 0.01, 0.02, 0.03, -0.01, -0.02, -0.03])  # symmetric about azimuth 0
    for centre in (0.0, 2 * np.pi - 0.015, 1.0):
        az = np.mod(centre + offsets, 2 * np.pi)
        Y = np.column_stack((np.full(7, 1e6), az, np.full(7, 0.5)))
        m = pts.mean(Y, model.residual)
        assert model.residual(m, np.array([1e6, centre, 0.5]))[1] == pytest.approx(0.0, abs=1e-12)
        np.testing.assert_allclose(pts.covariance(model.residual(Y, m))[1, 1], (2 * 14e-4) / 6, rtol=1e-9)


# -------------------------------------------------------------------------- linear-model filters


def linear_problem(seed: int, steps: int = 80):
    """Truth and measurements of a 3-D constant-velocity target sampled from the filter's own model."""
    rng = np.random.default_rng(seed)
    dyn = ConstantVelocity(sigma_accel=0.3)
    meas = PositionMeasurement(3)
    R = np.diag([4.0, 9.0, 1.0])
    P0 = np.diag([100.0, 100.0, 100.0, 4.0, 4.0, 4.0])
    x = rng.multivariate_normal(np.zeros(6), P0)
    times = np.cumsum(rng.uniform(0.2, 1.5, size=steps))
    truth, zs, t_prev = [], [], 0.0
    for t in times:
        dt = t - t_prev
        x = dyn.propagate(x, dt) + rng.multivariate_normal(np.zeros(6), dyn.process_noise(x, dt))
        truth.append(x)
        zs.append(meas.h(x, t) + rng.multivariate_normal(np.zeros(3), R))
        t_prev = t
    return dyn, meas, R, P0, times, np.array(truth), np.array(zs)


@pytest.mark.parametrize("alpha", [1e-3, 0.5, 1.0])
def test_ukf_equals_kf_on_a_linear_model(alpha):
    dyn, meas, R, P0, times, _, zs = linear_problem(seed=1)
    kf, ukf = KalmanFilter(dyn), UnscentedKalmanFilter(dyn, alpha=alpha)
    for f in (kf, ukf):
        f.initialise(np.zeros(6), P0, 0.0)
    for t, z in zip(times, zs):
        r_kf, r_ukf = kf.process(t, z, R, meas), ukf.process(t, z, R, meas)
        np.testing.assert_allclose(ukf.x, kf.x, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(ukf.P, kf.P, rtol=1e-8, atol=1e-9)
        assert r_ukf.nis == pytest.approx(r_kf.nis, rel=1e-7)


def test_ekf_equals_kf_on_a_linear_model():
    dyn, meas, R, P0, times, _, zs = linear_problem(seed=2)
    kf, ekf = KalmanFilter(dyn), ExtendedKalmanFilter(dyn)
    for f in (kf, ekf):
        f.initialise(np.zeros(6), P0, 0.0)
    for t, z in zip(times, zs):
        kf.process(t, z, R, meas)
        ekf.process(t, z, R, meas)
    np.testing.assert_allclose(ekf.x, kf.x, rtol=1e-12)
    np.testing.assert_allclose(ekf.P, kf.P, rtol=1e-12)


@pytest.mark.parametrize("name", ["kf", "ekf", "ukf"])
def test_nees_and_nis_of_a_linear_problem_are_chi_square(name):
    """Monte Carlo over runs sampled from the filter's own model: NEES ~ chi2(6), NIS ~ chi2(3)."""
    runs, steps = 40, 80
    nees = np.empty((runs, steps))
    nis = np.empty((runs, steps))
    for run in range(runs):
        dyn, meas, R, P0, times, truth, zs = linear_problem(seed=100 + run, steps=steps)
        f = make_filter(name, dyn)
        f.initialise(np.zeros(6), P0, 0.0)
        for k, (t, z) in enumerate(zip(times, zs)):
            nis[run, k] = f.process(t, z, R, meas).nis
            e = f.x - truth[k]
            nees[run, k] = e @ np.linalg.solve(f.P, e)
    # Ensemble NEES per step: 95 % band of chi2(runs * 6) / runs; a consistent filter leaves ~5 % out.
    lo, hi = chi2.ppf([0.025, 0.975], runs * 6) / runs
    inside = np.mean((nees.mean(axis=0) > lo) & (nees.mean(axis=0) < hi))
    assert inside >= 0.88
    lo, hi = chi2.ppf([0.005, 0.995], runs * steps * 6) / (runs * steps)
    assert lo < nees.mean() < hi
    # Innovations are white: their time-and-ensemble average has the exact chi2(runs*steps*3) band.
    lo, hi = chi2.ppf([0.005, 0.995], runs * steps * 3) / (runs * steps)
    assert lo < nis.mean() < hi


def test_a_mistuned_filter_fails_the_nees_check():
    """The NEES check can fail: a filter told the noise is 100x smaller is overconfident."""
    dyn, meas, R, P0, times, truth, zs = linear_problem(seed=7)
    f = KalmanFilter(ConstantVelocity(sigma_accel=0.003))
    f.initialise(np.zeros(6), P0, 0.0)
    nees = []
    for k, (t, z) in enumerate(zip(times, zs)):
        f.process(t, z, R / 100.0, meas)
        e = f.x - truth[k]
        nees.append(e @ np.linalg.solve(f.P, e))
    assert np.mean(nees) > 50.0


# ------------------------------------------------------------------------------ second-order EKF


class PositionMeasurementWithHessian(PositionMeasurement):
    """The linear position measurement with its (zero) Hessians, for the second-order EKF."""

    def hessian(self, x, t):
        return np.zeros((len(self.labels), len(x), len(x)))


def test_second_order_ekf_equals_ekf_on_a_linear_model():
    dyn, _, R, P0, times, _, zs = linear_problem(seed=4)
    meas = PositionMeasurementWithHessian(3)
    ekf, ekf2 = ExtendedKalmanFilter(dyn), SecondOrderEKF(dyn)
    for f in (ekf, ekf2):
        f.initialise(np.zeros(6), P0, 0.0)
    for t, z in zip(times, zs):
        assert ekf2.process(t, z, R, meas).nis == pytest.approx(ekf.process(t, z, R, meas).nis, rel=1e-12)
    np.testing.assert_allclose(ekf2.x, ekf.x, rtol=1e-12)
    np.testing.assert_allclose(ekf2.P, ekf.P, rtol=1e-12)


def test_second_order_ekf_needs_a_hessian():
    dyn, meas, R, P0, times, _, zs = linear_problem(seed=4, steps=2)
    f = SecondOrderEKF(dyn)
    f.initialise(np.zeros(6), P0, 0.0)
    with pytest.raises(TypeError, match="ekf2: the measurement model PositionMeasurement has no hessian"):
        f.process(times[0], zs[0], R, meas)


def test_second_order_moments_are_the_radar_measurement_moments_after_a_first_scan():
    """With the ~25 km cross-range spread of a 1 deg scan at 1500 km, the range's mean sits hundreds of
    metres beyond h(mean) (the shell's sag) and its spread is ~10 sigma_r: the second-order terms give both
    (Monte Carlo, 200 000 samples), the first-order ones neither."""
    model = GroundRadarModel(*STATION)
    t = 4400.0
    x = state_at_look_angles(model, t, 1.5e6, 2.0, 0.3, np.array([0.0, 7e3, 0.0]))
    J = model.position_jacobian(model.h(x, t), t)
    P = np.zeros((6, 6))
    P[0:3, 0:3] = J @ R_RADAR @ J.T
    P[3:6, 3:6] = np.eye(3)
    samples = np.random.default_rng(0).multivariate_normal(x, P, size=200_000)
    Z = model.h(samples, t)
    z0 = model.h(x, t)
    mc_mean = z0 + np.mean(model.residual(Z, z0), axis=0)
    D = model.residual(Z, mc_mean)
    mc_cov = D.T @ D / len(D)
    H = model.jacobian(x, t)
    bias, B = second_order_moments(model.hessian(x, t), P)
    assert bias[0] > 300.0 and np.sqrt(B[0, 0]) > 300.0  # >> sigma_r = 31.6 m
    assert abs(mc_mean[0] - (z0[0] + bias[0])) < 3.0  # MC error ~1 m
    assert abs(mc_mean[0] - z0[0]) > 100 * abs(mc_mean[0] - (z0[0] + bias[0]))
    S = H @ P @ H.T + B
    np.testing.assert_allclose(np.diag(S), np.diag(mc_cov), rtol=0.01)
    sd = np.sqrt(np.diag(mc_cov))
    # correlations: MC noise ~0.002; the third-order terms a second-order filter ignores add ~0.01
    np.testing.assert_allclose(S / np.outer(sd, sd), mc_cov / np.outer(sd, sd), atol=0.02)
    assert mc_cov[0, 0] > 50 * (H @ P @ H.T)[0, 0]


# --------------------------------------------------------------------- batch re-linearisation


@pytest.mark.parametrize("name", ["ekf", "ekf2", "ukf"])
def test_relinearised_filters_equal_the_kf_on_a_linear_deterministic_model(name, monkeypatch):
    """Gauss-Newton on a linear problem is the Kalman filter: re-solving changes nothing."""
    dyn, _, R, P0, times, _, zs = linear_problem(seed=5, steps=60)
    dyn = ConstantVelocity(sigma_accel=0.0)
    meas = PositionMeasurementWithHessian(3)
    solves = []
    solve = PassBatch.solve
    monkeypatch.setattr(PassBatch, "solve", lambda self, guess: solves.append(len(self)) or solve(self, guess))
    kf, f = KalmanFilter(dyn), make_filter(name, dyn, relinearise=1.5, relinearise_from=2)
    for g in (kf, f):
        g.initialise(np.ones(6), P0, 0.0)
    for t, z in zip(times, zs):
        kf.process(t, z, R, meas)
        assert f.process(t, z, R, meas).accepted
        np.testing.assert_allclose(f.x, kf.x, rtol=1e-7, atol=1e-7)
        np.testing.assert_allclose(f.P, kf.P, rtol=1e-6, atol=1e-9)
    assert solves == [2, 3, 5, 8, 12, 18, 27, 41]


def radar_scans(seconds: float, seed: int):
    """The first ``seconds`` of the leo_radar pass: (model, times, truth, scans, first-scan prior)."""
    model = GroundRadarModel(*STATION, theta0=np.radians(40.0))
    times = 4321.0 + 0.1 * np.arange(round(seconds / 0.1) + 1)
    truth = propagate(propagate(CHAMP, np.array([0.0, times[0]]))[-1], times)
    rng = np.random.default_rng(seed)
    z = np.array([model.h(x, t) for x, t in zip(truth, times)]) + rng.normal(size=(len(times), 3)) * 0.017
    z[:, 0] = [model.h(x, t)[0] for x, t in zip(truth, times)] + rng.normal(size=len(times)) * np.sqrt(1000.0)
    z[:, 1] = np.mod(z[:, 1], 2 * np.pi)
    x0, P0 = initial_state_from_scan(z[0], R_RADAR, model, times[0], 8000.0)
    return model, times, truth, z, x0, P0


def test_batch_solution_is_the_least_squares_minimum_and_beats_the_recursive_estimate():
    model, times, _, z, x0, P0 = radar_scans(4.0, seed=3)
    dyn = OrbitJ2Dynamics(sigma_accel=0.0)
    ekf = ExtendedKalmanFilter(dyn)
    ekf.initialise(x0, P0, times[0])
    batch = PassBatch(dyn, x0, P0, times[0])
    for t, zk in zip(times[1:], z[1:]):
        ekf.process(t, zk, R_RADAR, model)
        batch.add(t, zk, R_RADAR, model)
    guess = dyn.propagate(ekf.x, times[0] - times[-1])
    x, P, passes = batch.solve(guess)
    assert passes >= 2

    def residuals(x_start):
        out, state, t_prev = [batch.W0 @ (x_start - x0)], x_start, times[0]
        for s in batch.scans:
            state, t_prev = dyn.propagate(state, s.t - t_prev), s.t
            out.append(s.W @ model.residual(s.z, model.h(state, s.t)))
        return np.concatenate(out)

    ref = least_squares(residuals, guess, x_scale=np.sqrt(np.diag(P0)), xtol=1e-12, ftol=1e-12)
    x_ref = dyn.propagate(ref.x, times[-1] - times[0])
    e = x - x_ref
    assert e @ np.linalg.solve(P, e) < 1e-4
    assert batch.linearise(dyn.propagate(x, times[0] - times[-1])).cost < batch.linearise(guess).cost


def test_relinearise_needs_a_deterministic_model_and_a_growth_factor():
    with pytest.raises(ValueError, match="ukf: relinearise needs a deterministic process model"):
        make_filter("ukf", OrbitJ2Dynamics(sigma_accel=0.5), relinearise=1.5)
    with pytest.raises(ValueError, match=r"ekf2: relinearise must be 0 \(off\) or a growth factor > 1, got 1"):
        make_filter("ekf2", OrbitJ2Dynamics(sigma_accel=0.0), relinearise=1.0)
    with pytest.raises(ValueError, match="relinearise_from must be a positive number of scans"):
        make_filter("ekf", OrbitJ2Dynamics(sigma_accel=0.0), relinearise=2.0, relinearise_from=0)
    assert make_filter("ekf", OrbitJ2Dynamics(sigma_accel=0.5)).relinearise == 0.0  # off: Q allowed


# ---------------------------------------------------------------------------- guarded processing


@pytest.mark.parametrize("name", ["kf", "ekf", "ukf"])
def test_bad_and_out_of_order_measurements_leave_the_filter_untouched(name):
    dyn, meas, R, P0, times, _, zs = linear_problem(seed=3, steps=5)
    f = make_filter(name, dyn)
    f.initialise(np.zeros(6), P0, 0.0)
    f.process(times[1], zs[1], R, meas)
    x, P, t = f.x.copy(), f.P.copy(), f.t
    for bad_t, bad_z, bad_R in [
        (times[2], np.array([1.0, np.nan, 0.0]), R),
        (times[2], np.array([np.inf, 0.0, 0.0]), R),
        (times[2], zs[2], np.diag([np.inf, 1.0, 1.0])),
        (np.nan, zs[2], R),
        (times[0], zs[0], R),
    ]:
        result = f.process(bad_t, bad_z, bad_R, meas)
        assert not result.accepted and result.reason
        np.testing.assert_array_equal(f.x, x)
        np.testing.assert_array_equal(f.P, P)
        assert f.t == t
    assert "out-of-order" in f.process(times[0], zs[0], R, meas).reason
    assert f.process(times[2], zs[2], R, meas).accepted


@pytest.mark.parametrize("name", ["kf", "ekf", "ukf"])
def test_covariance_repair_is_reported(name):
    f = make_filter(name, ConstantVelocity(sigma_accel=0.0, ndim=1))
    f.initialise(np.zeros(2), np.array([[1.0, 1.0], [1.0, 1.0 - 1e-9]]), 0.0)  # slightly indefinite
    result = f.process(0.0, np.array([0.1]), np.array([[1.0]]), PositionMeasurement(1))
    assert result.accepted
    assert any("repaired" in w for w in result.warnings)
    assert np.all(np.linalg.eigvalsh(f.P) > 0.0)


# ------------------------------------------------------------------------ radar: azimuth wrap


def state_at_look_angles(model, t, rng_m, az, el, vel_enu):
    T = model.eci_to_enu_rotation(t)
    u = rng_m * np.array([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)])
    r_ecef = model.station_ecef + enu_rotation(model.lat_rad, model.lon_rad).T @ u
    return np.concatenate((ecef_to_eci(r_ecef, t, model.theta0), T.T @ vel_enu))


class UnwrappedRadar(GroundRadarModel):
    """The radar with angle wrapping switched off: what the test must catch."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.angle_indices = ()


def crossing_run(name: str, model: GroundRadarModel, az0: float) -> tuple[np.ndarray, float]:
    """NIS of 30 noisy scans of a target moving east from azimuth az0 (~6 mrad/s), and the final
    position error in units of the filter's own position sigma."""
    dyn = OrbitJ2Dynamics(sigma_accel=1.0)
    t0 = 100.0
    x0 = state_at_look_angles(model, t0, 1.2e6, az0, 0.4, np.array([7e3, 0.0, 0.0]))
    f = make_filter(name, dyn)
    f.initialise(x0, np.diag([2e3**2] * 3 + [30.0**2] * 3), t0)  # sigma points span +-4 mrad
    rng = np.random.default_rng(5)
    truth, nis = x0, []
    for k in range(1, 31):
        t = t0 + 0.1 * k
        truth = dyn.propagate(truth, 0.1)
        z = model.h(truth, t) + rng.normal(size=3) * np.sqrt(np.diag(R_RADAR))
        z[1] = np.mod(z[1], 2 * np.pi)
        nis.append(f.process(t, z, R_RADAR, model).nis)
    e = f.x[0:3] - truth[0:3]
    return np.array(nis), float(np.sqrt(e @ np.linalg.solve(f.P[0:3, 0:3], e)))


@pytest.mark.parametrize("name", ["ekf", "ekf2", "ukf"])
def test_azimuth_crossing_north_gives_no_innovation_spike(name):
    """A target crossing north (azimuth 2 pi -> 0) mid-run behaves as one crossing east does."""
    model = GroundRadarModel(*STATION)
    az0 = -0.006
    assert model.h(state_at_look_angles(model, 100.0, 1.2e6, az0, 0.4, np.zeros(3)), 100.0)[1] > 6.0
    for start in (az0, np.pi / 2 + az0):
        nis, position_sigmas = crossing_run(name, model, start)
        assert np.max(nis) < chi2.ppf(0.9999, 3) and position_sigmas < 4.0
    # Without wrapping the same crossing breaks the filter: an innovation of ~2 pi, or (UKF) sigma points
    # straddling north averaging to a wrong azimuth.
    nis, position_sigmas = crossing_run(name, UnwrappedRadar(*STATION), az0)
    assert np.max(nis) > 1e3 or position_sigmas > 10.0


# ------------------------------------------------------------------------------------ registry


def test_registry_builds_filters_and_names_errors():
    dyn = OrbitJ2Dynamics(sigma_accel=1e-3)
    assert set(filter_names()) >= {"kf", "ekf", "ukf"}
    assert isinstance(make_filter("ekf", dyn), ExtendedKalmanFilter)
    ukf = make_filter("ukf", dyn, alpha=0.5, beta=2.0, kappa=0.0)
    assert isinstance(ukf, UnscentedKalmanFilter) and ukf.points.alpha == 0.5
    with pytest.raises(ValueError, match=r"unknown filter 'enkf'; allowed: .*ekf.*kf.*ukf"):
        make_filter("enkf", dyn)
    with pytest.raises(ValueError, match=r"ukf: unknown parameter\(s\) gamma; allowed: alpha, beta, kappa"):
        make_filter("ukf", dyn, gamma=1.0)
    with pytest.raises(ValueError, match=r"^ukf: alpha must be in \(0, 1\], got -1$"):
        make_filter("ukf", dyn, alpha=-1)
    with pytest.raises(ValueError, match=r"ekf: unknown parameter\(s\) alpha; allowed: relinearise, relin"):
        make_filter("ekf", dyn, alpha=0.5)
    with pytest.raises(ValueError, match=r"kf: unknown parameter\(s\) alpha; allowed: none"):
        make_filter("kf", dyn, alpha=0.5)
    assert isinstance(make_filter("ekf2", dyn), SecondOrderEKF)
