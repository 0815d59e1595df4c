"""TRIAD and the least-squares (SVD) Wahba solution against known rotations; the quaternion convention; the
covariances against Monte Carlo."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from star_tracker.attitude import (
    davenport_quaternion,
    error_angle,
    error_components,
    error_vector,
    matrix_from_quaternion,
    quaternion_from_matrix,
    residuals,
    rotation_matrix,
    triad,
    triad_matrix,
    wahba,
    wahba_matrix,
)


def star_field(rng, n, half_width=0.15):
    b = np.column_stack([rng.uniform(-half_width, half_width, (n, 2)), np.ones(n)])
    return b / np.linalg.norm(b, axis=1, keepdims=True)


def noisy(rng, b, sigma):
    """b perturbed by σ rad per axis perpendicular to it."""
    e1 = np.cross(b, [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(b, e1)
    s = np.broadcast_to(sigma, (len(b),))[:, None]
    v = b + s * (rng.normal(size=(len(b), 1)) * e1 + rng.normal(size=(len(b), 1)) * e2)
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_the_quaternion_convention_is_scalar_first_and_rotates_icrs_into_the_camera():
    # a camera turned so that ICRS x is seen along camera y: A r = b with r = x, b = y
    A = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(A @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    q = quaternion_from_matrix(A)
    np.testing.assert_allclose(q, [np.cos(np.pi / 4), 0.0, 0.0, np.sin(np.pi / 4)], atol=1e-12)
    np.testing.assert_allclose(matrix_from_quaternion(q), A, atol=1e-12)
    assert quaternion_from_matrix(Rotation.from_rotvec([0.0, 0.0, 1.9 * np.pi]).as_matrix())[0] >= 0


def test_the_rotation_routines_agree_with_scipy_from_tiny_angles_to_half_turns():
    """The hand-written conversions (attitude.py: scipy Rotations cost most of a tracker's frame) against
    scipy's, on random rotations and on the series and branch boundaries."""
    rng = np.random.default_rng(11)
    axes = rng.normal(size=(6, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = [0.0, 1e-9, 1e-4, 9.9e-4, 1.0001e-3, 0.5, 2.0, np.pi - 1e-6, np.pi]
    rotations = list(Rotation.random(100, random_state=rng)) + [
        Rotation.from_rotvec(a * n) for a in angles for n in axes
    ]
    for rot in rotations:
        A, rotvec = rot.as_matrix(), rot.as_rotvec()
        q = quaternion_from_matrix(A)
        assert q[0] >= 0 and abs(abs(q @ rot.as_quat(scalar_first=True)) - 1.0) < 1e-12
        np.testing.assert_allclose(matrix_from_quaternion(q), A, atol=1e-12)
        np.testing.assert_allclose(rotation_matrix(rotvec) - np.eye(3), A - np.eye(3), rtol=1e-9, atol=1e-15)
        assert error_angle(A, np.eye(3)) == pytest.approx(rot.magnitude(), abs=1e-12)
        if rot.magnitude() < np.pi - 1e-7:  # at a half turn the sign of the rotation vector is arbitrary
            np.testing.assert_allclose(error_vector(A, np.eye(3)), -rotvec, rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("seed", range(5))
def test_triad_and_wahba_recover_a_known_rotation_exactly(seed):
    rng = np.random.default_rng(seed)
    A = Rotation.random(random_state=rng).as_matrix()
    b = star_field(rng, 8)
    r = b @ A  # r = Aᵀ b
    np.testing.assert_allclose(triad_matrix(b[0], b[3], r[0], r[3]), A, atol=1e-12)
    np.testing.assert_allclose(triad(b, r, 1e-5).matrix, A, atol=1e-12)
    np.testing.assert_allclose(wahba_matrix(b, r), A, atol=1e-12)
    sol = wahba(b, r, 1e-5)
    assert error_angle(sol.matrix, A) < 1e-10 and np.max(sol.residuals) < 1e-10
    np.testing.assert_allclose(np.abs(sol.quaternion), np.abs(quaternion_from_matrix(A)), atol=1e-10)


@pytest.mark.parametrize("seed", range(4))
def test_the_svd_solution_equals_davenports_q_method_under_noise(seed):
    rng = np.random.default_rng(seed)
    A = Rotation.random(random_state=rng).as_matrix()
    b = star_field(rng, 12)
    r = b @ A
    w = rng.uniform(0.5, 2.0, 12)
    bn = noisy(rng, b, 1e-3)
    q_svd = quaternion_from_matrix(wahba_matrix(bn, r, w))
    np.testing.assert_allclose(davenport_quaternion(bn, r, w), q_svd, atol=1e-9)
    np.testing.assert_allclose(davenport_quaternion(b, r), quaternion_from_matrix(A), atol=1e-12)


def test_error_components_split_the_boresight_pointing_from_the_roll():
    A = Rotation.random(random_state=5).as_matrix()
    A_est = Rotation.from_rotvec([-3e-5, -4e-5, -7e-5]).as_matrix() @ A  # δθ = (3, 4, 7)·1e-5
    cross, roll = error_components(A_est, A)
    assert cross == pytest.approx(5e-5, rel=1e-6) and roll == pytest.approx(7e-5, rel=1e-6)


def test_wahba_with_two_stars_equals_the_rotation_and_refuses_one():
    rng = np.random.default_rng(9)
    A = Rotation.random(random_state=rng).as_matrix()
    b = star_field(rng, 2)
    np.testing.assert_allclose(wahba_matrix(b, b @ A), A, atol=1e-12)
    with pytest.raises(ValueError):
        wahba(b[:1], b[:1] @ A, 1e-5)
    with pytest.raises(ValueError):
        triad(b[:1], b[:1] @ A, 1e-5)


def test_the_error_vector_has_the_documented_sign():
    A = Rotation.random(random_state=1).as_matrix()
    dtheta = np.array([1e-4, -2e-4, 3e-4])
    A_est = Rotation.from_rotvec(-dtheta).as_matrix() @ A  # Â = exp(−[δθ×]) A
    np.testing.assert_allclose(error_vector(A_est, A), dtheta, atol=1e-12)
    assert error_angle(A_est, A) == pytest.approx(np.linalg.norm(dtheta))


def test_the_covariances_match_monte_carlo():
    rng = np.random.default_rng(4)
    A = Rotation.random(random_state=rng).as_matrix()
    b = star_field(rng, 7)
    r = b @ A
    sigma = np.array([1e-4, 3e-4, 1e-4, 2e-4, 1e-4, 1e-4, 1e-4])
    e_triad, e_wahba = [], []
    for _ in range(4000):
        bn = noisy(rng, b, sigma)
        e_triad.append(error_vector(triad(bn, r, sigma, pair=(0, 1)).matrix, A))
        e_wahba.append(error_vector(wahba(bn, r, sigma).matrix, A))
    for samples, predicted in (
        (e_triad, triad(b, r, sigma, pair=(0, 1)).covariance),
        (e_wahba, wahba(b, r, sigma).covariance),
    ):
        samples = np.array(samples)
        # each direction's variance within 12 % (4000 samples: ±4.5 % at 2σ)
        for u in np.linalg.eigh(predicted)[1].T:
            assert np.var(samples @ u) == pytest.approx(u @ predicted @ u, rel=0.12)
        assert np.abs(samples.mean(axis=0)).max() < 0.1 * np.sqrt(np.diag(predicted)).max()


def test_the_all_star_solution_beats_two_star_triad_under_noise():
    rng = np.random.default_rng(7)
    A = Rotation.random(random_state=rng).as_matrix()
    b = star_field(rng, 20)
    r = b @ A
    e_t, e_w = [], []
    for _ in range(300):
        bn = noisy(rng, b, 1e-4)
        e_t.append(error_angle(triad(bn, r, 1e-4).matrix, A))
        e_w.append(error_angle(wahba(bn, r, 1e-4).matrix, A))
    assert np.sqrt(np.mean(np.square(e_w))) < 0.5 * np.sqrt(np.mean(np.square(e_t)))


def test_residuals_are_the_angles_between_observed_and_predicted():
    A = np.eye(3)
    b = np.array([[0.0, 0.0, 1.0], [np.sin(1e-3), 0.0, np.cos(1e-3)]])
    r = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(residuals(A, b, r), [0.0, 1e-3], atol=1e-15)
