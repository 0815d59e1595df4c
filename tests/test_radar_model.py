"""Ground radar measurement model (paper 000, eqs. 8-16) and the first-scan initialisation."""

import numpy as np
import pytest

from bench_models.radar import GroundRadarModel
from orbit_sim.cowell import propagate
from orbit_sim.frames import ecef_to_eci, enu_rotation, geodetic_to_ecef
from orbit_sim.kepler import kepler_to_cartesian
from orbit_sim.passes import look_angles
from tracker_filters.initialisation import circular_orbit_velocity_prior, initial_state_from_scan

STATION = (np.radians(78.15306), np.radians(16.02889), 445.0)
THETA0 = np.radians(40.0)
R = np.diag([1000.0, 0.017**2, 0.017**2])
LEO_SPEED = 7.7e3


def target_state(
    model: GroundRadarModel, t: float, rng_m: float, az: float, el: float, vel_eci: np.ndarray
) -> np.ndarray:
    """ECI state of a target at (range, azimuth, elevation) from the station at time t."""
    enu = rng_m * np.array([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)])
    r_ecef = model.station_ecef + enu_rotation(model.lat_rad, model.lon_rad).T @ enu
    return np.concatenate((ecef_to_eci(r_ecef, t, model.theta0), vel_eci))


def geometries():
    """A spread of (t, range, azimuth, elevation, velocity) including azimuths next to north."""
    rng = np.random.default_rng(3)
    cases = [(4400.0, 1.2e6, 1e-4, 0.3), (10.0, 9e5, 2 * np.pi - 1e-4, 0.6), (0.0, 2e6, 3.0, 0.09)]
    cases += [
        (rng.uniform(0, 6000), rng.uniform(5e5, 2e6), rng.uniform(0, 2 * np.pi), rng.uniform(0.05, 1.4))
        for _ in range(5)
    ]
    return [(t, r, a, e, rng.normal(size=3) * LEO_SPEED / np.sqrt(3)) for t, r, a, e in cases]


@pytest.fixture(params=[False, True], ids=["rae", "rae+rdot"])
def model(request):
    return GroundRadarModel(*STATION, theta0=THETA0, with_range_rate=request.param)


def test_h_recovers_constructed_look_angles_and_matches_passes(model):
    for t, rng_m, az, el, v in geometries():
        x = target_state(model, t, rng_m, az, el, v)
        z = model.h(x, t)
        np.testing.assert_allclose(z[0], rng_m, rtol=1e-12)
        assert abs(model.residual(z, np.array([rng_m, az, el] + [0.0] * (len(z) - 3)))[1]) < 1e-9
        assert z[2] == pytest.approx(el, abs=1e-9)
        assert 0.0 <= z[1] < 2 * np.pi
        other = look_angles(np.array([t]), x[None], *STATION, theta0=THETA0)
        np.testing.assert_allclose([o[0] for o in other], z[0:3], rtol=1e-12, atol=1e-9)


def test_jacobian_matches_central_differences(model):
    for t, rng_m, az, el, v in geometries():
        x = target_state(model, t, rng_m, az, el, v)
        H = model.jacobian(x, t)
        steps = np.array([1.0, 1.0, 1.0, 1e-2, 1e-2, 1e-2])
        H_fd = np.column_stack(
            [model.residual(model.h(x + s * e, t), model.h(x - s * e, t)) / (2 * s) for s, e in zip(steps, np.eye(6))]
        )
        scale = np.abs(H_fd).max(axis=1, keepdims=True)
        np.testing.assert_allclose(H / scale, H_fd / scale, atol=1e-7)


def test_hessian_matches_central_differences_of_the_jacobian(model):
    for t, rng_m, az, el, v in geometries():
        x = target_state(model, t, rng_m, az, el, v)
        Hs = model.hessian(x, t)
        assert Hs.shape == (len(model.labels), 6, 6)
        np.testing.assert_allclose(Hs, Hs.transpose(0, 2, 1), rtol=0, atol=1e-20)
        steps = np.array([10.0, 10.0, 10.0, 0.1, 0.1, 0.1])
        fd = np.stack(
            [(model.jacobian(x + s * e, t) - model.jacobian(x - s * e, t)) / (2 * s) for s, e in zip(steps, np.eye(6))],
            axis=2,
        )  # fd[i, j, k] = d H_ij / d x_k
        scale = np.abs(fd).max(axis=(1, 2), keepdims=True)
        np.testing.assert_allclose(Hs / scale, fd / scale, atol=1e-7)
        # range, azimuth and elevation do not depend on the velocity
        assert not Hs[0:3, 3:6, :].any() and not Hs[0:3, :, 3:6].any()


def test_range_hessian_is_the_curvature_of_the_range_shell(model):
    """Along a cross-range direction the range grows by d^2 / (2 range): the second-order term's meaning."""
    t, rng_m = 4400.0, 1.5e6
    x = target_state(model, t, rng_m, 0.7, 0.3, np.zeros(3))
    los = x[0:3] - ecef_to_eci(model.station_ecef, t, model.theta0)
    cross = np.cross(los, [0.0, 0.0, 1.0])
    d = 25e3 * np.concatenate((cross / np.linalg.norm(cross), np.zeros(3)))
    assert 0.5 * d @ model.hessian(x, t)[0] @ d == pytest.approx(25e3**2 / (2 * rng_m), rel=1e-12)
    assert model.h(x + d, t)[0] - rng_m == pytest.approx(25e3**2 / (2 * rng_m), rel=1e-3)


def test_range_rate_is_the_time_derivative_of_range_on_the_rotating_earth():
    model = GroundRadarModel(*STATION, theta0=THETA0, with_range_rate=True)
    x0 = kepler_to_cartesian(
        6739137.0, 0.00033, np.radians(87.2346), np.radians(303.3713), np.radians(81.5653), np.radians(80.0)
    )
    t, d = 4500.0, 0.01
    states = propagate(x0, np.array([0.0, t - d, t, t + d]))
    rdot_fd = (model.h(states[3], t + d)[0] - model.h(states[1], t - d)[0]) / (2 * d)
    assert model.h(states[2], t)[3] == pytest.approx(rdot_fd, abs=1e-4)
    # The test can tell: ignoring the station's motion (omega x r) would be off by tens of m/s.
    u = model.enu(states[2], t)
    naive = u @ (model.eci_to_enu_rotation(t) @ states[2, 3:6]) / np.linalg.norm(u)
    assert abs(naive - rdot_fd) > 10.0


def test_batch_h_equals_rowwise_and_extra_state_components_are_ignored(model):
    t = 4400.0
    X = np.array([target_state(model, t, r, a, e, v) for _, r, a, e, v in geometries()])
    Z = model.h(X, t)
    np.testing.assert_allclose(Z, np.array([model.h(x, t) for x in X]), rtol=1e-13, atol=1e-12)
    X8 = np.column_stack((X, np.ones((len(X), 2))))
    np.testing.assert_allclose(model.h(X8, t), Z, rtol=1e-13)
    H8 = model.jacobian(X8[0], t)
    assert H8.shape == (len(model.labels), 8) and not H8[:, 6:].any()


def test_elevation_and_visibility_helper():
    model = GroundRadarModel(*STATION, theta0=THETA0)
    t = 1234.5
    zenith = target_state(model, t, 5e5, 0.0, np.pi / 2, np.zeros(3))
    assert model.elevation(zenith, t) == pytest.approx(np.pi / 2, abs=1e-9)
    X = np.array([target_state(model, t, 1e6, 1.0, el, np.zeros(3)) for el in (-0.2, 0.05, 0.9)])
    np.testing.assert_allclose(model.elevation(X, t), [-0.2, 0.05, 0.9], atol=1e-9)


def test_residual_wraps_azimuth_across_north():
    model = GroundRadarModel(*STATION)
    d = model.residual(np.array([1e6, 0.01, 0.3]), np.array([1e6 + 5.0, 2 * np.pi - 0.01, 0.3]))
    np.testing.assert_allclose(d, [-5.0, 0.02, 0.0], atol=1e-12)


def test_position_from_measurement_inverts_h_and_its_jacobian():
    model = GroundRadarModel(*STATION, theta0=THETA0)
    for t, rng_m, az, el, v in geometries():
        x = target_state(model, t, rng_m, az, el, v)
        z = model.h(x, t)
        np.testing.assert_allclose(model.position_from_measurement(z, t), x[0:3], atol=1e-6)
        J = model.position_jacobian(z, t)
        steps = np.array([1.0, 1e-7, 1e-7])
        J_fd = np.column_stack(
            [
                (model.position_from_measurement(z + s * e, t) - model.position_from_measurement(z - s * e, t))
                / (2 * s)
                for s, e in zip(steps, np.eye(3))
            ]
        )
        np.testing.assert_allclose(J, J_fd, rtol=1e-6, atol=1e-6 * np.abs(J).max())


def test_station_is_where_geodetic_to_ecef_puts_it():
    model = GroundRadarModel(*STATION, theta0=THETA0)
    np.testing.assert_allclose(model.station_ecef, geodetic_to_ecef(*STATION))
    assert model.labels == ("range", "azimuth", "elevation")
    assert tuple(model.angle_indices) == (1, 2)


@pytest.mark.parametrize("method", ["unscented", "jacobian"])
def test_first_scan_initialisation_covers_the_scan_error(method):
    """Monte Carlo: the first-scan position error is zero-mean with the covariance P0 claims."""
    model = GroundRadarModel(*STATION, theta0=THETA0)
    t = 4400.0
    truth = target_state(model, t, 1.5e6, 0.4, 0.1, np.array([1e3, -2e3, 7e3]))
    z_true = model.h(truth, t)
    rng = np.random.default_rng(11)
    nees, errors = [], []
    for _ in range(2000):
        z = z_true + rng.normal(size=3) * np.sqrt(np.diag(R))
        x0, P0 = initial_state_from_scan(z, R, model, t, velocity_sigma=8000.0, method=method)
        e = x0[0:3] - truth[0:3]
        errors.append(e)
        nees.append(e @ np.linalg.solve(P0[0:3, 0:3], e))
    np.testing.assert_allclose(x0[3:6], 0.0)
    np.testing.assert_allclose(P0[3:6, 3:6], np.eye(3) * 8000.0**2)
    assert not P0[0:3, 3:6].any()
    # Cross-range spread ~ range * sigma_angle = 25 km; its curvature puts the scan ~0.4 km behind.
    cov = np.cov(np.array(errors).T)
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), np.sqrt(np.diag(P0[0:3, 0:3])), rtol=0.1)
    if method == "unscented":
        assert 2.0 < np.mean(nees) < 4.0  # chi-square(3) mean 3; the 99% band of 2000 samples is +-0.15
    else:
        assert np.mean(nees) > 30.0  # the first-order map ignores the range shell's curvature


def test_velocity_prior_options():
    model = GroundRadarModel(*STATION, theta0=THETA0)
    z = np.array([1.5e6, 0.4, 0.1])
    x0, P0 = initial_state_from_scan(
        z, R, model, 0.0, velocity_sigma=np.array([1.0, 2.0, 3.0]), velocity_mean=np.array([4.0, 5.0, 6.0])
    )
    np.testing.assert_allclose(x0[3:6], [4.0, 5.0, 6.0])
    np.testing.assert_allclose(np.diag(P0)[3:6], [1.0, 4.0, 9.0])
    mean, cov = circular_orbit_velocity_prior(x0[0:3], radial_sigma=10.0)
    u = x0[0:3] / np.linalg.norm(x0[0:3])
    assert u @ cov @ u == pytest.approx(100.0)
    assert np.trace(cov) - 100.0 == pytest.approx(3.986004418e14 / np.linalg.norm(x0[0:3]))
    x1, P1 = initial_state_from_scan(z, R, model, 0.0, velocity_sigma=cov, velocity_mean=mean)
    np.testing.assert_allclose(P1[3:6, 3:6], cov)
    with pytest.raises(ValueError, match="velocity_sigma"):
        initial_state_from_scan(z, R, model, 0.0, velocity_sigma=-1.0)
    with pytest.raises(ValueError, match="method"):
        initial_state_from_scan(z, R, model, 0.0, velocity_sigma=1.0, method="magic")
