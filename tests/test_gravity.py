"""Two-body + J2 acceleration (paper 000, eqs. 4-7) and its analytic Jacobian."""

import numpy as np
import pytest

from orbit_sim.constants import J2_EARTH, MU_EARTH, R_EARTH
from orbit_sim.gravity import acceleration, acceleration_jacobian, state_derivative

RNG = np.random.default_rng(1)
POSITIONS = [RNG.normal(size=3) * 4.0e6 + np.sign(RNG.normal(size=3)) * 3.0e6 for _ in range(5)]


def potential_energy(r: np.ndarray) -> float:
    """V = U_0 + U_J2 of paper eq. 4 (per unit mass), with sin(phi) = z / r; a = -grad V."""
    rn = np.linalg.norm(r)
    sin_phi = r[2] / rn
    return -MU_EARTH / rn + MU_EARTH / rn * (R_EARTH / rn) ** 2 * J2_EARTH / 2 * (3 * sin_phi**2 - 1)


def test_two_body_when_j2_is_zero():
    r = POSITIONS[0]
    np.testing.assert_allclose(acceleration(r, j2=0.0), -MU_EARTH * r / np.linalg.norm(r) ** 3, rtol=1e-14)


@pytest.mark.parametrize("r", POSITIONS)
def test_acceleration_is_minus_gradient_of_eq4_potential(r):
    h = 1.0
    grad = np.array([(potential_energy(r + h * e) - potential_energy(r - h * e)) / (2 * h) for e in np.eye(3)])
    np.testing.assert_allclose(acceleration(r), -grad, rtol=1e-7)


def test_j2_textbook_form():
    """Eq. 6 equals the usual form a = -mu r/r^3 [1 - 3/2 J2 (Re/r)^2 (5 z^2/r^2 - {1,1,3})]."""
    r = POSITIONS[1]
    rn = np.linalg.norm(r)
    k = 1.5 * J2_EARTH * (R_EARTH / rn) ** 2
    s = 5 * r[2] ** 2 / rn**2
    expected = -MU_EARTH * r / rn**3 * (1 - k * (s - np.array([1.0, 1.0, 3.0])))
    np.testing.assert_allclose(acceleration(r), expected, rtol=1e-13)


def test_j2_pulls_towards_equator():
    """Above the equatorial plane the J2 term adds a -z acceleration (oblate Earth)."""
    r = np.array([5.0e6, 0.0, 5.0e6])
    assert (acceleration(r) - acceleration(r, j2=0.0))[2] < 0.0


def test_batch_matches_rows():
    batch = np.array(POSITIONS)
    np.testing.assert_allclose(acceleration(batch), np.array([acceleration(r) for r in POSITIONS]), rtol=1e-15)


@pytest.mark.parametrize("j2", [J2_EARTH, 0.0])
@pytest.mark.parametrize("r", POSITIONS)
def test_jacobian_matches_finite_differences(r, j2):
    h = 1.0
    numeric = np.column_stack(
        [(acceleration(r + h * e, j2=j2) - acceleration(r - h * e, j2=j2)) / (2 * h) for e in np.eye(3)]
    )
    jac = acceleration_jacobian(r, j2=j2)
    np.testing.assert_allclose(jac, numeric, rtol=0, atol=1e-7 * np.abs(jac).max())


def test_jacobian_of_a_potential_field_is_symmetric():
    jac = acceleration_jacobian(POSITIONS[2])
    np.testing.assert_allclose(jac, jac.T, rtol=0, atol=1e-12 * np.abs(jac).max())


def test_state_derivative():
    y = np.concatenate((POSITIONS[3], [1.0, 2.0, 3.0]))
    dy = state_derivative(0.0, y, MU_EARTH, J2_EARTH, R_EARTH)
    np.testing.assert_array_equal(dy[:3], y[3:])
    np.testing.assert_allclose(dy[3:], acceleration(y[:3]), rtol=1e-15)
