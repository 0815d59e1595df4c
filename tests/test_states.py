"""State errors by the state's own rule: quaternions as rotations, angles wrapped, the rest differenced."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench_models.states import attitude_error, error_labels, rotation_vector, state_error


def quat(rotation: Rotation) -> np.ndarray:
    x, y, z, w = rotation.as_quat()  # scipy is scalar last
    return np.array([w, x, y, z])


def test_attitude_error_is_the_rotation_from_truth_to_estimate():
    truth = Rotation.from_euler("zyx", [30.0, -20.0, 10.0], degrees=True)
    delta = Rotation.from_rotvec([1e-4, -2e-4, 3e-4])
    estimate = delta * truth
    np.testing.assert_allclose(attitude_error(quat(estimate), quat(truth)), delta.as_rotvec(), atol=1e-13)


def test_q_and_minus_q_are_the_same_attitude():
    q = quat(Rotation.from_euler("x", 170.0, degrees=True))
    assert np.allclose(attitude_error(-q, q), 0.0)
    assert np.allclose(attitude_error(q, -q), 0.0)


def test_a_large_error_keeps_its_angle():
    truth = Rotation.identity()
    estimate = Rotation.from_rotvec([0.0, 0.0, 3.0])
    assert np.linalg.norm(attitude_error(quat(estimate), quat(truth))) == pytest.approx(3.0)
    assert np.allclose(rotation_vector(np.array([1.0, 0.0, 0.0, 0.0])), 0.0)


def test_the_difference_of_quaternions_is_not_the_error():
    truth = Rotation.identity()
    estimate = Rotation.from_rotvec([0.0, 0.0, 0.02])
    labels, e = state_error(["qw", "qx", "qy", "qz", "wx"], np.r_[-quat(estimate), 0.1], np.r_[quat(truth), 0.0])
    assert labels == ["rx", "ry", "rz", "wx"]
    np.testing.assert_allclose(e, [0.0, 0.0, 0.02, 0.1], atol=1e-12)


def test_angles_are_wrapped_and_other_components_differenced():
    labels, e = state_error(
        ["range", "azimuth", "x"], np.array([[10.0, 0.05, 1.0]]), np.array([[7.0, 2 * np.pi - 0.05, 3.0]])
    )
    assert labels == ["range", "azimuth", "x"]
    np.testing.assert_allclose(e, [[3.0, 0.1, -2.0]], atol=1e-12)
    assert error_labels(["x", "qw", "qx", "qy", "qz"]) == ["x", "rx", "ry", "rz"]
