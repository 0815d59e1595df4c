"""Image-plane motion models (paper eqs. 14–16): closed forms, Van Loan's Q, the limits between them."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad_vec
from scipy.linalg import expm

from star_tracker.motion import B, ConstantVelocity, CoordinatedTurn, H, turn_matrix, turn_noise, van_loan


def test_constant_velocity_discrete_is_the_papers_eq_15():
    dt, s = 0.1, 2.0
    F, Q = ConstantVelocity(s).transition(dt)
    np.testing.assert_allclose(F, [[1, dt, 0, 0], [0, 1, 0, 0], [0, 0, 1, dt], [0, 0, 0, 1]])
    E = np.array([[dt**2 / 2, 0], [dt, 0], [0, dt**2 / 2], [0, dt]])
    np.testing.assert_allclose(Q, E @ (s**2 * np.eye(2)) @ E.T)
    np.testing.assert_allclose(H @ np.array([1.0, 2.0, 3.0, 4.0]), [1.0, 3.0])


def test_constant_velocity_continuous_equals_van_loan_of_the_white_noise_acceleration():
    dt, s = 0.1, 3.0
    F, Q = ConstantVelocity(s, kind="continuous").transition(dt)
    A = np.zeros((4, 4))
    A[0, 1] = A[2, 3] = 1.0
    F2, Q2 = van_loan(A, s**2 * B @ B.T, dt)
    np.testing.assert_allclose(F, F2, atol=1e-14)
    np.testing.assert_allclose(Q, Q2, rtol=1e-10, atol=1e-16)


@pytest.mark.parametrize("omega", [0.3, -1.2, 5.0, 0.05, -2e-4, 1e-7])
def test_the_turn_models_transition_is_the_closed_form(omega):
    dt = 0.1
    F, _ = CoordinatedTurn(omega, 1.0).transition(dt)
    np.testing.assert_allclose(F, turn_matrix(omega, dt), atol=1e-12)
    np.testing.assert_allclose(F, expm(CoordinatedTurn(omega, 1.0).A * dt), atol=1e-14)


@pytest.mark.parametrize("omega", [2.0, -0.7, 0.09, -1e-3, 1e-6, 0.0])
def test_the_closed_form_turn_noise_equals_van_loan(omega):
    dt, q = 0.1, 2.5
    _, Q = van_loan(CoordinatedTurn(omega, 1.0).A, q * B @ B.T, dt)
    np.testing.assert_allclose(turn_noise(omega, dt, q), Q, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(CoordinatedTurn(omega, np.sqrt(q)).transition(dt)[1], Q, rtol=1e-9, atol=1e-15)


def test_the_turn_models_q_is_the_integral_of_the_papers_q3():
    m, dt, s = CoordinatedTurn(0.8, 2.0), 0.5, 2.0
    _, Q = m.transition(dt)
    q2 = np.diag([0.0, s**2, 0.0, s**2])
    integral, _ = quad_vec(lambda tau: expm(m.A * (dt - tau)) @ q2 @ expm(m.A * (dt - tau)).T, 0.0, dt)
    np.testing.assert_allclose(Q, integral, rtol=1e-8, atol=1e-14)
    assert np.all(np.linalg.eigvalsh(Q) > 0)


def test_the_turn_model_tends_to_constant_velocity():
    F0, Q0 = ConstantVelocity(1.5, kind="continuous").transition(0.1)
    F, Q = CoordinatedTurn(1e-9, 1.5).transition(0.1)
    np.testing.assert_allclose(F, F0, atol=1e-9)
    np.testing.assert_allclose(Q, Q0, atol=1e-12)
    np.testing.assert_allclose(turn_matrix(0.0, 0.1), F0)


def test_a_star_circling_the_boresight_is_propagated_exactly_by_the_turn_model():
    # image rotating at w about the centre: p(t) = R(w t) p0, v = w × p
    w, dt, p0 = 0.2, 0.1, np.array([300.0, -120.0])

    def state(t):
        c, s = np.cos(w * t), np.sin(w * t)
        p = np.array([[c, -s], [s, c]]) @ p0
        v = w * np.array([-p[1], p[0]])
        return np.array([p[0], v[0], p[1], v[1]])

    F, _ = CoordinatedTurn(w, 0.0).transition(dt)
    x = state(0.0)
    for _ in range(49):
        x = F @ x
    np.testing.assert_allclose(x, state(49 * dt), atol=1e-8)


def test_bad_parameters_are_refused():
    with pytest.raises(ValueError):
        ConstantVelocity(1.0, kind="jerk")
    with pytest.raises(ValueError):
        ConstantVelocity(-1.0)
    with pytest.raises(ValueError):
        CoordinatedTurn(0.1, -1.0)
