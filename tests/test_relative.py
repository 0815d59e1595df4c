"""LVLH frame, axis conventions, Hill/CW solution and the drift-free truth formation (orbit_sim.relative, .hill)."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from orbit_sim import cowell, gravity, hill, kepler, relative
from orbit_sim.constants import MU_EARTH

A_REF = 7100e3
N_REF = np.sqrt(MU_EARTH / A_REF**3)
PERIOD = 2.0 * np.pi / N_REF


def chief_state(inc_deg: float = 45.0, u0_deg: float = 0.0) -> np.ndarray:
    return kepler.kepler_to_cartesian(A_REF, 0.0, np.radians(inc_deg), 0.3, 0.0, np.radians(u0_deg))


def test_lvlh_basis_is_a_right_handed_rotation_aligned_with_r_and_h():
    c = chief_state()
    C = relative.lvlh_basis(c)
    assert np.allclose(C @ C.T, np.eye(3), atol=1e-14)
    assert np.isclose(np.linalg.det(C), 1.0)
    assert np.allclose(C[0], c[0:3] / np.linalg.norm(c[0:3]))
    h = np.cross(c[0:3], c[3:6])
    assert np.allclose(C[2], h / np.linalg.norm(h))
    assert C[1] @ c[3:6] > 0.99 * np.linalg.norm(c[3:6])  # y along the flight direction (circular orbit)


@pytest.mark.parametrize("with_accel", [False, True])
def test_eci_lvlh_round_trip_single_and_batch(with_accel):
    rng = np.random.default_rng(1)
    chiefs = np.array([chief_state(45.0, u) for u in (0.0, 33.0, 170.0)])
    accel = gravity.acceleration(chiefs[:, 0:3]) if with_accel else None
    rel = rng.normal(size=(3, 6)) * np.array([1e3, 1e3, 1e3, 1.0, 1.0, 1.0])
    deputies = relative.lvlh_to_eci(chiefs, rel, accel)
    back = relative.eci_to_lvlh(chiefs, deputies, accel)
    assert np.allclose(back, rel, rtol=0, atol=1e-9)
    single = relative.eci_to_lvlh(chiefs[1], deputies[1], None if accel is None else accel[1])
    assert np.allclose(single, rel[1], atol=1e-9)
    # a relative state of zero is the chief itself
    assert np.allclose(relative.lvlh_to_eci(chiefs[0], np.zeros(6)), chiefs[0])


def test_relative_velocity_is_the_derivative_of_relative_position_with_exact_frame_rate():
    """With the chief's acceleration the frame rate includes its x-axis part and rho_dot = d rho / dt."""
    c0 = chief_state(45.0, 30.0)
    t = np.linspace(0.0, 600.0, 601)
    chief = cowell.propagate(c0, t)
    accel = gravity.acceleration(chief[:, 0:3])
    deputy = cowell.propagate(relative.lvlh_to_eci(c0, np.array([0.0, 1000.0, 0.0, 0.5, 0.0, 1.0]), accel[0]), t)
    exact = relative.eci_to_lvlh(chief, deputy, accel)
    approx = relative.eci_to_lvlh(chief, deputy)
    fd = (exact[2:, 0:3] - exact[:-2, 0:3]) / 2.0
    assert np.max(np.abs(fd - exact[1:-1, 3:6])) < 2e-6
    # neglecting the out-of-plane frame rotation costs ~1 mm/s at 1 km under J2
    assert np.max(np.abs(fd - approx[1:-1, 3:6])) > 2e-4


def test_cw_matches_two_body_relative_motion_at_short_range():
    """Signs and axes of the CW equations agree with the truth frame: 100 m formation, two-body, 1 orbit."""
    c0 = chief_state(45.0, 0.0)
    rel0 = np.array([20.0, 100.0, -30.0, 0.05, -2.0 * N_REF * 20.0, 0.1])
    t = np.linspace(0.0, PERIOD, 61)
    chief = cowell.propagate(c0, t, j2=0.0)
    deputy = cowell.propagate(relative.lvlh_to_eci(c0, rel0), t, j2=0.0)
    truth = relative.eci_to_lvlh(chief, deputy)
    cw = hill.cw_propagate(rel0, t, N_REF)
    assert np.max(np.linalg.norm(cw[:, 0:3] - truth[:, 0:3], axis=1)) < 0.1  # nonlinearity ~ rho^2 / r


@pytest.mark.parametrize("dt", [-300.0, 0.0, 1.0, 10.0, 1234.5, 2.0 * PERIOD])
def test_cw_stm_is_expm_of_cw_matrix(dt):
    assert np.allclose(hill.cw_stm(N_REF, dt), expm(hill.cw_matrix(N_REF) * dt), rtol=1e-9, atol=1e-9)


def test_cw_stm_matches_numerical_integration_and_batches():
    A = hill.cw_matrix(N_REF)
    x0 = np.array([100.0, -200.0, 50.0, 0.3, -0.1, 0.2])
    t = np.linspace(0.0, 1.5 * PERIOD, 40)
    sol = solve_ivp(lambda _, x: A @ x, (t[0], t[-1]), x0, t_eval=t, rtol=1e-12, atol=1e-10)
    assert np.allclose(hill.cw_propagate(x0, t, N_REF), sol.y.T, atol=1e-6)
    stms = hill.cw_stm(N_REF, t)
    assert stms.shape == (40, 6, 6)
    assert np.allclose(stms[17], hill.cw_stm(N_REF, t[17]))
    # semigroup: Phi(t1 + t2) = Phi(t1) Phi(t2)
    assert np.allclose(hill.cw_stm(N_REF, 700.0), hill.cw_stm(N_REF, 300.0) @ hill.cw_stm(N_REF, 400.0), atol=1e-9)


def test_along_radial_convention_axes():
    """Paper 001: X along-track, Y radial, Z completes a right-handed frame, so Z = -orbit normal."""
    M = relative.convention_matrix("along_radial")
    C = relative.lvlh_basis(chief_state())
    X_hat, Y_hat, Z_hat = M @ C  # the paper's axes in ECI
    assert np.allclose(X_hat, C[1]) and np.allclose(Y_hat, C[0])
    assert np.allclose(np.cross(X_hat, Y_hat), Z_hat)
    assert np.allclose(Z_hat, -C[2])
    assert np.allclose(relative.to_convention([1.0, 2.0, 3.0], "along_radial"), [2.0, 1.0, -3.0])


def test_conventions_convert_6_and_9_vectors_and_batches():
    rng = np.random.default_rng(2)
    v9 = rng.normal(size=(5, 9))
    for conv in relative.CONVENTIONS:
        out = relative.to_convention(v9, conv)
        assert np.allclose(relative.from_convention(out, conv), v9)
        assert np.allclose(relative.to_convention(v9[2, 0:6], conv), out[2, 0:6])
    out = relative.to_convention(v9, "along_radial")
    for block in range(3):
        b = slice(3 * block, 3 * block + 3)
        assert np.allclose(out[:, b], v9[:, b][:, [1, 0, 2]] * [1.0, 1.0, -1.0])
    assert np.allclose(relative.to_convention(v9, "radial_along_normal"), v9)
    with pytest.raises(ValueError):
        relative.to_convention(np.zeros(4), "along_radial")
    with pytest.raises(ValueError):
        relative.convention_matrix("hill")


def test_paper001_printed_hill_equations_are_the_same_motion():
    """Paper 001 eq. 5 (X along, Y radial) integrated as printed == CW solution converted to its axes."""
    w = 2.0 * np.pi / 7200.0
    A001 = np.zeros((6, 6))
    A001[0:3, 3:6] = np.eye(3)
    A001[3, 4] = -2.0 * w
    A001[4, 1] = 3.0 * w * w
    A001[4, 3] = 2.0 * w
    A001[5, 2] = -w * w
    X0 = np.array([400.0, 500.0, 200.0, 0.1, -0.2, 0.05])  # paper 001 axes
    t = np.linspace(0.0, 7200.0, 73)
    sol = solve_ivp(lambda _, x: A001 @ x, (0.0, t[-1]), X0, t_eval=t, rtol=1e-12, atol=1e-10)
    internal = hill.cw_propagate(relative.from_convention(X0, "along_radial"), t, w)
    assert np.allclose(relative.to_convention(internal, "along_radial"), sol.y.T, atol=1e-6)


def truth_drift(c0: np.ndarray, rel: np.ndarray) -> float:
    """Along-track drift [m/orbit] of the two-body + J2 truth: orbit-mean y, orbit 3 minus orbit 1, / 2."""
    t = np.linspace(0.0, 3.0 * PERIOD, 301)
    chief = cowell.propagate(c0, t)
    accel = gravity.acceleration(chief[:, 0:3])
    y = relative.eci_to_lvlh(chief, cowell.propagate(relative.lvlh_to_eci(c0, rel, accel[0]), t), accel)[:, 1]
    return float(y[200:300].mean() - y[0:100].mean()) / 2.0


def test_drift_free_removes_the_truth_along_track_drift():
    c0 = chief_state(98.0, 0.0)
    rel0 = np.array([0.0, 1000.0, 0.0, 500.0 * N_REF, 0.0, 1000.0 * N_REF])  # CW-bounded PCO, 1 km
    fixed = relative.drift_free(c0, rel0)
    assert np.allclose(np.delete(fixed, 4), np.delete(rel0, 4))
    before, after = truth_drift(c0, rel0), truth_drift(c0, fixed)
    assert abs(before) > 1.0  # the CW condition does drift in the J2 truth (~1.6 m/orbit here)
    assert abs(after) < 0.01 * abs(before)
