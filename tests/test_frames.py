"""ECI <-> ECEF (rotation about z), WGS84 geodetic <-> ECEF, and the ENU frame (paper 000 eqs. 8-10)."""

import numpy as np
import pytest

from orbit_sim.constants import OMEGA_EARTH, R_EARTH, WGS84_F
from orbit_sim.frames import (
    earth_rotation_angle,
    ecef_to_eci,
    ecef_to_eci_state,
    ecef_to_geodetic,
    eci_to_ecef,
    eci_to_ecef_state,
    enu_rotation,
    geodetic_to_ecef,
)

RNG = np.random.default_rng(5)
STATES = np.hstack((RNG.normal(size=(8, 3)) * 7e6, RNG.normal(size=(8, 3)) * 7e3))


def test_earth_rotation_angle():
    assert earth_rotation_angle(0.0, 0.3) == pytest.approx(0.3)
    assert earth_rotation_angle(86164.0905, 0.0) == pytest.approx(2 * np.pi, rel=1e-6)


def test_eci_x_axis_seen_from_rotated_earth():
    """After a quarter turn of the Earth, the inertial x axis lies along ECEF -y."""
    t = (np.pi / 2) / OMEGA_EARTH
    np.testing.assert_allclose(eci_to_ecef(np.array([1.0, 0.0, 0.0]), t), [0.0, -1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(eci_to_ecef(np.array([1.0, 2.0, 3.0]), 0.0), [1.0, 2.0, 3.0])


def test_position_round_trip_with_per_row_times():
    t = np.linspace(0.0, 5000.0, len(STATES))
    r = STATES[:, :3]
    np.testing.assert_allclose(ecef_to_eci(eci_to_ecef(r, t, 1.1), t, 1.1), r, atol=1e-6)
    np.testing.assert_allclose(eci_to_ecef(r, t, 1.1)[3], eci_to_ecef(r[3], t[3], 1.1), atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(eci_to_ecef(r, t), axis=1), np.linalg.norm(r, axis=1))


def test_state_round_trip():
    for t in (0.0, 1234.5):
        back = ecef_to_eci_state(eci_to_ecef_state(STATES, t, 0.7), t, 0.7)
        np.testing.assert_allclose(back, STATES, atol=1e-6)
    single = eci_to_ecef_state(STATES[0], 42.0, 0.7)
    np.testing.assert_allclose(single, eci_to_ecef_state(STATES, 42.0, 0.7)[0], atol=1e-9)


def test_ecef_velocity_is_time_derivative_of_ecef_position():
    """For straight-line inertial motion r(t) = r0 + v t, compare with a central difference."""
    r0, v = STATES[1, :3], STATES[1, 3:]
    t, h = 300.0, 1e-3
    numeric = (eci_to_ecef(r0 + v * (t + h), t + h, 0.2) - eci_to_ecef(r0 + v * (t - h), t - h, 0.2)) / (2 * h)
    analytic = eci_to_ecef_state(np.concatenate((r0 + v * t, v)), t, 0.2)[3:]
    np.testing.assert_allclose(analytic, numeric, atol=1e-5)


def test_ground_point_moves_with_the_earth_in_eci():
    station = geodetic_to_ecef(0.4, 1.0, 100.0)
    eci = ecef_to_eci_state(np.concatenate((station, np.zeros(3))), 500.0)
    np.testing.assert_allclose(eci[3:], np.cross([0.0, 0.0, OMEGA_EARTH], eci[:3]), atol=1e-9)


def test_geodetic_known_points():
    np.testing.assert_allclose(geodetic_to_ecef(0.0, 0.0, 0.0), [R_EARTH, 0.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(geodetic_to_ecef(np.pi / 2, 0.3, 0.0), [0.0, 0.0, R_EARTH * (1 - WGS84_F)], atol=1e-6)
    np.testing.assert_allclose(geodetic_to_ecef(0.0, np.pi / 2, 1000.0), [0.0, R_EARTH + 1000.0, 0.0], atol=1e-6)


@pytest.mark.parametrize("lat_deg", [-90.0, -60.0, -1.0, 0.0, 33.3, 78.15, 89.999, 90.0])
@pytest.mark.parametrize("h", [-100.0, 0.0, 445.0, 400e3, 2000e3])
def test_geodetic_round_trip(lat_deg, h):
    lat, lon = np.radians(lat_deg), np.radians(-123.4)
    lat2, lon2, h2 = ecef_to_geodetic(geodetic_to_ecef(lat, lon, h))
    assert lat2 == pytest.approx(lat, abs=1e-11)
    assert h2 == pytest.approx(h, abs=1e-4)
    if abs(lat_deg) < 90.0:
        assert lon2 == pytest.approx(lon, abs=1e-11)


def test_enu_rotation_is_proper_and_known_at_origin():
    m = enu_rotation(0.7, -2.0)
    np.testing.assert_allclose(m @ m.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(m) == pytest.approx(1.0)
    np.testing.assert_allclose(enu_rotation(0.0, 0.0), [[0, 1, 0], [0, 0, 1], [1, 0, 0]], atol=1e-15)


def test_point_above_station_is_at_zenith():
    lat, lon = np.radians(78.15), np.radians(16.03)
    station = geodetic_to_ecef(lat, lon, 445.0)
    enu = enu_rotation(lat, lon) @ (geodetic_to_ecef(lat, lon, 400e3) - station)
    np.testing.assert_allclose(enu, [0.0, 0.0, 400e3 - 445.0], atol=1e-6)
    assert np.degrees(np.arcsin(enu[2] / np.linalg.norm(enu))) == pytest.approx(90.0)
    north = enu_rotation(lat, lon) @ (geodetic_to_ecef(lat + 1e-3, lon, 445.0) - station)
    east = enu_rotation(lat, lon) @ (geodetic_to_ecef(lat, lon + 1e-3, 445.0) - station)
    assert north[1] > 0 and abs(north[0]) < 1e-6 * north[1]
    assert east[0] > 0 and abs(east[1]) < 1e-3 * east[0]
