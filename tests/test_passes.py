"""Look angles, visibility windows, pass finding, and the chosen leo_radar geometry.

LEO_RADAR_* below are the scenario constants (paper 000 gives neither station nor epoch): the EISCAT
Svalbard Radar (78°09'11" N, 16°01'44" E, 445 m) and an Earth rotation angle of 40° at the epoch give a
first pass of the CHAMP orbit of ~420 s above the 5° mask, ~72 min after the epoch, whose azimuth
crosses north (0 / 2 pi).
"""

import numpy as np
import pytest

from orbit_sim.cowell import propagate
from orbit_sim.frames import ecef_to_eci, enu_rotation, geodetic_to_ecef
from orbit_sim.kepler import kepler_to_cartesian
from orbit_sim.passes import elevation_series, find_pass, look_angles, visibility_windows

LEO_RADAR_STATION = (np.radians(78.15306), np.radians(16.02889), 445.0)
LEO_RADAR_THETA0 = np.radians(40.0)
MASK = np.radians(5.0)
CHAMP = kepler_to_cartesian(
    6739137.0, 0.00033, np.radians(87.2346), np.radians(303.3713), np.radians(81.5653), np.radians(80.0)
)


def test_visibility_windows_interpolates_crossings():
    t = np.arange(0.0, 11.0)
    el = np.array([-2, -1, 1, 3, 1, -1, -3, -1, 1, 2, 3], dtype=float)
    windows = visibility_windows(t, el, 0.0)
    assert len(windows) == 2
    np.testing.assert_allclose(windows[0], (1.5, 4.5, 3.0))
    np.testing.assert_allclose(windows[1], (7.5, 10.0, 3.0))  # still open: clipped at the end
    assert visibility_windows(t, -np.abs(el) - 5.0, 0.0) == []
    assert visibility_windows(t, el, 0.5)[0][0] == pytest.approx(1.75)


def test_look_angles_known_directions():
    """Targets placed at known (range, azimuth, elevation) in the station's ENU frame."""
    lat, lon, h = LEO_RADAR_STATION
    t, theta0 = 1000.0, 0.3
    rng = np.array([500e3, 800e3, 1200e3, 1500e3, 900e3])
    az = np.radians([0.0, 90.0, 200.0, 359.9, 45.0])
    el = np.radians([90.0, 45.0, 10.0, 5.0, 30.0])
    enu = rng[:, None] * np.column_stack((np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)))
    r_ecef = geodetic_to_ecef(lat, lon, h) + enu @ enu_rotation(lat, lon)
    got_rng, got_az, got_el = look_angles(np.full(5, t), ecef_to_eci(r_ecef, t, theta0), lat, lon, h, theta0)
    np.testing.assert_allclose(got_rng, rng, atol=1e-6)
    np.testing.assert_allclose(got_el, el, atol=1e-9)
    np.testing.assert_allclose(got_az[1:], az[1:], atol=1e-9)  # azimuth undefined at the zenith
    assert np.all((got_az >= 0.0) & (got_az < 2 * np.pi))


def test_find_pass_agrees_with_fine_sampling():
    lat, lon, h = np.radians(-30.0), np.radians(20.0), 0.0
    p = find_pass(CHAMP, lat, lon, h, 1.0, MASK, 6 * 3600.0)
    t = np.arange(p.t_rise - 30.0, p.t_set + 30.0, 0.5)
    states = propagate(CHAMP, np.concatenate(([0.0], t)))[1:]
    windows = visibility_windows(t, elevation_series(t, states, lat, lon, h, 1.0), MASK)
    assert len(windows) == 1
    np.testing.assert_allclose(windows[0][:2], (p.t_rise, p.t_set), atol=0.01)
    assert windows[0][2] == pytest.approx(p.max_elevation, abs=1e-4)
    assert find_pass(CHAMP, lat, lon, h, 1.0, MASK, p.t_rise - 60.0) is None


def test_leo_radar_pass_lasts_420_s_and_crosses_north():
    p = find_pass(CHAMP, *LEO_RADAR_STATION, LEO_RADAR_THETA0, MASK, 4 * 3600.0)
    assert p is not None
    assert p.duration == pytest.approx(420.0, abs=15.0)
    assert p.t_rise < 2 * 3600.0
    t = np.arange(p.t_rise, p.t_set, 0.1)
    states = propagate(CHAMP, np.concatenate(([0.0], t)))[1:]
    rng, az, el = look_angles(t, states, *LEO_RADAR_STATION, LEO_RADAR_THETA0)
    assert np.all(el >= MASK - 1e-6)
    assert np.any(np.abs(np.diff(az)) > np.pi)  # azimuth wraps through north
    assert 700e3 < rng.min() < rng.max() < 2000e3
