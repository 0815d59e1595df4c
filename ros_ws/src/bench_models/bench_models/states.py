"""How a state's error is computed, by the kind of its components (told by their labels).

An estimate and the truth are compared component block by component block, each by its own rule:

* an attitude quaternion, labels ``qw qx qy qz`` in one block (scalar first, Hamilton, rotating the reference frame into
  the body frame): the error is the rotation vector of dq = q_est * conj(q_true), i.e. the small rotation
  that takes the true attitude to the estimate (angle = |error|, in rad); q and -q are the same attitude;
* an angle (bench_engine.labels.angle_labels): the difference wrapped to (-pi, pi];
* anything else: the plain difference x_est - x_true.

:func:`state_error` returns the error vector with its labels (a quaternion block becomes ``rx ry rz``), which
the metrics use for RMSE, NEES (against the estimate's covariance of the same error labels) and the like.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bench_engine.labels import QUATERNION, ROTATION, angle_labels
from orbit_sim.angles import wrap_angle


def quaternion_multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product p * q of scalar-first quaternions, batched over leading axes."""
    pw, pv = p[..., :1], p[..., 1:]
    qw, qv = q[..., :1], q[..., 1:]
    w = pw * qw - np.sum(pv * qv, axis=-1, keepdims=True)
    v = pw * qv + qw * pv + np.cross(pv, qv)
    return np.concatenate([w, v], axis=-1)


def rotation_vector(q: np.ndarray) -> np.ndarray:
    """Rotation vector (axis * angle, angle in [0, pi]) of unit quaternions (..., 4), scalar first."""
    q = np.asarray(q, dtype=float)
    q = np.where(q[..., :1] < 0.0, -q, q)  # q and -q: the same rotation, take the short way
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, q[..., :1])
    scale = np.divide(angle, s, out=np.full_like(s, 2.0), where=s > 1e-15)  # small angles: 2 v
    return v * scale


def attitude_error(q_est: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    """Rotation vector of q_est * conj(q_true) (..., 3), both normalised first."""
    q_est = np.asarray(q_est, dtype=float)
    q_true = np.asarray(q_true, dtype=float)
    q_est = q_est / np.linalg.norm(q_est, axis=-1, keepdims=True)
    q_true = q_true / np.linalg.norm(q_true, axis=-1, keepdims=True)
    return rotation_vector(quaternion_multiply(q_est, q_true * np.array([1.0, -1.0, -1.0, -1.0])))


def error_labels(labels: Sequence[str]) -> list[str]:
    """The labels of :func:`state_error`'s output for a state with ``labels``."""
    labels = list(labels)
    if all(q in labels for q in QUATERNION):
        i = labels.index(QUATERNION[0])
        return labels[:i] + list(ROTATION) + [lab for lab in labels[i:] if lab not in QUATERNION]
    return labels


def state_error(labels: Sequence[str], x_est: np.ndarray, x_true: np.ndarray) -> tuple[list[str], np.ndarray]:
    """(error labels, error (..., m)) of estimates against the truth, both (..., n) with ``labels``."""
    labels = list(labels)
    x_est = np.asarray(x_est, dtype=float)
    x_true = np.asarray(x_true, dtype=float)
    plain = [i for i, lab in enumerate(labels) if lab not in QUATERNION]
    diff = x_est[..., plain] - x_true[..., plain]
    angles = angle_labels()
    for j, i in enumerate(plain):
        if labels[i] in angles:
            diff[..., j] = wrap_angle(diff[..., j])
    if not all(q in labels for q in QUATERNION):
        return labels, diff
    idx = [labels.index(q) for q in QUATERNION]
    rot = attitude_error(x_est[..., idx], x_true[..., idx])
    out_labels = error_labels(labels)
    split = out_labels.index(ROTATION[0])
    return out_labels, np.concatenate([diff[..., :split], rot, diff[..., split:]], axis=-1)
