"""Cowell propagation (paper 000, eq. 7): invariants, J2 secular rates, and the RK4 predictor."""

import numpy as np
import pytest

from orbit_sim.constants import J2_EARTH, MU_EARTH, R_EARTH
from orbit_sim.cowell import propagate, rk4
from orbit_sim.kepler import cartesian_to_kepler, kepler_to_cartesian

CHAMP = kepler_to_cartesian(
    6739137.0, 0.00033, np.radians(87.2346), np.radians(303.3713), np.radians(81.5653), np.radians(80.0)
)
PERIOD = 2 * np.pi * np.sqrt(6739137.0**3 / MU_EARTH)


def energy(s: np.ndarray, j2: float) -> np.ndarray:
    """Specific orbital energy including the J2 potential of eq. 4 (s is (K, 6))."""
    r = np.linalg.norm(s[:, :3], axis=1)
    sin_phi = s[:, 2] / r
    v_j2 = MU_EARTH / r * (R_EARTH / r) ** 2 * j2 / 2 * (3 * sin_phi**2 - 1)
    return 0.5 * np.sum(s[:, 3:] ** 2, axis=1) - MU_EARTH / r + v_j2


@pytest.mark.parametrize("j2", [0.0, J2_EARTH])
def test_energy_conserved(j2):
    s = propagate(CHAMP, np.linspace(0.0, 3 * PERIOD, 301), j2=j2)
    e = energy(s, j2)
    assert np.max(np.abs(e - e[0])) < 1e-10 * abs(e[0])


def test_two_body_angular_momentum_conserved_and_matches_kepler():
    times = np.linspace(0.0, 3 * PERIOD, 301)
    s = propagate(CHAMP, times, j2=0.0)
    h = np.cross(s[:, :3], s[:, 3:])
    np.testing.assert_allclose(h, np.tile(h[0], (len(times), 1)), rtol=0, atol=1e-10 * np.linalg.norm(h[0]))
    n = 2 * np.pi / PERIOD
    exact = kepler_to_cartesian(
        6739137.0,
        0.00033,
        np.radians(87.2346),
        np.radians(303.3713),
        np.radians(81.5653),
        np.radians(80.0) + n * times[-1],
    )
    np.testing.assert_allclose(s[-1, :3], exact[:3], atol=1e-3)


def test_j2_conserves_only_the_z_angular_momentum():
    s = propagate(CHAMP, np.linspace(0.0, 2 * PERIOD, 201))
    h = np.cross(s[:, :3], s[:, 3:])
    assert np.max(np.abs(h[:, 2] - h[0, 2])) < 1e-10 * np.linalg.norm(h[0])
    # The x-y components precess (nodal regression): J2 is actually acting.
    assert np.max(np.abs(h[:, 0] - h[0, 0])) > 1e-5 * np.linalg.norm(h[0])


def test_state0_is_at_first_time():
    later = propagate(CHAMP, np.array([0.0, 100.0, 250.0]))
    shifted = propagate(later[1], np.array([100.0, 250.0]))
    np.testing.assert_allclose(shifted, later[1:], atol=1e-6)
    back = propagate(later[2], np.array([250.0, 0.0]))
    np.testing.assert_allclose(back[-1], CHAMP, atol=1e-5)


def test_j2_secular_rates_match_classical_theory():
    """Orbit-averaged RAAN and perigee drift over ~1 day vs dOmega/dt and domega/dt (mean elements).

    A moderately eccentric orbit is used so that the argument of perigee is well defined; the
    tolerance (2 %) catches a wrong sign or factor in the J2 term.
    """
    a, e, i = 7.5e6, 0.05, np.radians(40.0)
    n = np.sqrt(MU_EARTH / a**3)
    period = 2 * np.pi / n
    orbits, per_orbit = int(86400.0 // period), 200
    t = np.linspace(0.0, orbits * period, orbits * per_orbit + 1)[:-1]
    s = propagate(kepler_to_cartesian(a, e, i, 1.0, 2.0, 0.5), t, rtol=1e-10)
    elements = [cartesian_to_kepler(x) for x in s]
    mean_t = t.reshape(orbits, per_orbit).mean(axis=1)

    def orbit_averaged_slope(key: str) -> float:
        angle = np.unwrap([el[key] for el in elements]).reshape(orbits, per_orbit).mean(axis=1)
        return np.polyfit(mean_t, angle, 1)[0]

    k = n * J2_EARTH * (R_EARTH / (a * (1 - e * e))) ** 2
    assert orbit_averaged_slope("raan") == pytest.approx(-1.5 * k * np.cos(i), rel=0.02)
    assert orbit_averaged_slope("argp") == pytest.approx(0.75 * k * (5 * np.cos(i) ** 2 - 1), rel=0.02)


def test_rk4_matches_propagate():
    for dt, tol in [(0.1, 1e-6), (10.0, 1e-4), (-60.0, 1e-3)]:
        np.testing.assert_allclose(rk4(CHAMP, dt)[:3], propagate(CHAMP, [0.0, dt])[-1, :3], atol=tol)
    long = propagate(CHAMP, [0.0, 600.0])[-1]
    np.testing.assert_allclose(rk4(CHAMP, 600.0, max_step=1.0), long, atol=1e-5)


def test_rk4_substeps_and_identity():
    ten = CHAMP
    for _ in range(10):
        ten = rk4(ten, 10.0)
    np.testing.assert_allclose(rk4(CHAMP, 100.0, max_step=10.0), ten, rtol=1e-14, atol=1e-8)
    np.testing.assert_array_equal(rk4(CHAMP, 0.0), CHAMP)


def test_rk4_batch_matches_single_and_j2_switch():
    rng = np.random.default_rng(3)
    batch = CHAMP + rng.normal(size=(13, 6)) * np.array([1e3] * 3 + [1.0] * 3)
    out = rk4(batch, 0.1)
    assert out.shape == (13, 6)
    np.testing.assert_allclose(out, np.array([rk4(x, 0.1) for x in batch]), rtol=1e-15, atol=1e-9)
    two_body = propagate(CHAMP, [0.0, 60.0], j2=0.0)[-1]
    np.testing.assert_allclose(rk4(CHAMP, 60.0, j2=0.0, max_step=1.0), two_body, atol=1e-5)
