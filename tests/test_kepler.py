"""Kepler's equation and element <-> Cartesian conversions (CHAMP orbit of paper 000, Table 1)."""

import numpy as np
import pytest

from orbit_sim.constants import MU_EARTH, R_EARTH
from orbit_sim.kepler import cartesian_to_kepler, kepler_to_cartesian, solve_kepler

CHAMP = dict(
    a=6739137.0,
    e=0.00033,
    i=np.radians(87.2346),
    raan=np.radians(303.3713),
    argp=np.radians(81.5653),
    M=np.radians(80.0),
)


def assert_elements_close(got: dict, want: dict, angle_tol: float = 1e-9) -> None:
    assert got["a"] == pytest.approx(want["a"], rel=1e-12)
    assert got["e"] == pytest.approx(want["e"], abs=1e-12)
    for key in ("i", "raan", "argp", "M"):
        diff = np.angle(np.exp(1j * (got[key] - want[key])))
        assert abs(diff) < angle_tol, key


@pytest.mark.parametrize("e", [0.0, 0.00033, 0.1, 0.5, 0.9, 0.99])
def test_solve_kepler_satisfies_equation(e):
    M = np.linspace(-np.pi, 3 * np.pi, 101)
    E = solve_kepler(M, e)
    np.testing.assert_allclose(E - e * np.sin(E), M, atol=1e-12)


def test_solve_kepler_scalar_known_value():
    E = solve_kepler(np.pi / 2, 0.5)
    assert isinstance(E, float)
    assert E - 0.5 * np.sin(E) == pytest.approx(np.pi / 2, abs=1e-14)
    assert E == pytest.approx(2.0, abs=0.1)


def test_champ_round_trip():
    assert_elements_close(cartesian_to_kepler(kepler_to_cartesian(**CHAMP)), CHAMP)


def test_champ_state_invariants():
    s = kepler_to_cartesian(**CHAMP)
    r, v = s[:3], s[3:]
    a, e, i, raan = CHAMP["a"], CHAMP["e"], CHAMP["i"], CHAMP["raan"]
    assert 0.5 * v @ v - MU_EARTH / np.linalg.norm(r) == pytest.approx(-MU_EARTH / (2 * a), rel=1e-12)
    h = np.cross(r, v)
    assert np.linalg.norm(h) == pytest.approx(np.sqrt(MU_EARTH * a * (1 - e * e)), rel=1e-12)
    h_dir = np.array([np.sin(i) * np.sin(raan), -np.sin(i) * np.cos(raan), np.cos(i)])
    np.testing.assert_allclose(h / np.linalg.norm(h), h_dir, atol=1e-12)
    # The paper quotes a ~360 km altitude for CHAMP.
    assert 355e3 < np.linalg.norm(r) - R_EARTH < 366e3


def test_random_orbits_round_trip():
    rng = np.random.default_rng(7)
    for _ in range(50):
        el = dict(
            a=rng.uniform(6.6e6, 4.5e7),
            e=rng.uniform(0.001, 0.8),
            i=rng.uniform(0.05, 3.09),
            raan=rng.uniform(0, 2 * np.pi),
            argp=rng.uniform(0, 2 * np.pi),
            M=rng.uniform(0, 2 * np.pi),
        )
        assert_elements_close(cartesian_to_kepler(kepler_to_cartesian(**el)), el, angle_tol=1e-8)


def test_perigee_position_known_answer():
    """i = 0 approached, raan = argp = M = 0: perigee on +x at a(1 - e), speed along +y."""
    a, e = 7.0e6, 0.1
    s = kepler_to_cartesian(a, e, 1e-9, 0.0, 0.0, 0.0)
    np.testing.assert_allclose(s[:3], [a * (1 - e), 0, 0], atol=1e-6)
    v_p = np.sqrt(MU_EARTH / a * (1 + e) / (1 - e))
    np.testing.assert_allclose(s[3:], [0, v_p, 0], atol=1e-4)
