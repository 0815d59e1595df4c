"""Attitude from star directions: TRIAD (two stars, as in the paper) and the least-squares solution of Wahba's
problem over all stars (SVD; Davenport's q-method as an independent check), with their attitude-error
covariances, and the attitude error (angle, vector, cross-boresight and roll parts).

Convention (used by every module of the package and by the published attitude estimates):
- The attitude matrix A is camera(body)-from-ICRS: a star with ICRS unit vector r is seen along b = A r in
  the camera frame (camera.py).
- The quaternion q = (qw, qx, qy, qz), scalar first, Hamilton product, is the rotation whose matrix is A:
  A = R(q) = ``scipy.spatial.transform.Rotation.from_quat(q, scalar_first=True).as_matrix()``, i.e. it
  rotates ICRS coordinates into camera coordinates (the same convention as tetra3rs'
  ``SolveResult.quaternion`` / ``rotation_matrix_icrs_to_camera``). The sign is fixed by qw >= 0.
- The attitude error of an estimate Â is the small rotation δθ (camera frame) with Â = exp(−[δθ×]) A, i.e.
  Â Aᵀ ≈ I − [δθ×]; its angle |δθ| = arccos((tr(Â Aᵀ) − 1)/2) (the paper's eq. 20 measures the angle between
  true and estimated attitude; this is the angle of the error rotation). Covariances are of δθ, in the camera
  frame, rad².

Wahba's problem: minimise Σ w_i |b_i − A r_i|². With B = Σ w_i b_i r_iᵀ = U S Vᵀ, the optimum is
A = U diag(1, 1, det U det V) Vᵀ (Markley 1988). For centroid noise of σ_i rad per axis on b_i (the QUEST
measurement model, Shuster & Oh 1981), w_i = 1/σ_i² and the error covariance is
P = (Σ (I − b_i b_iᵀ)/σ_i²)⁻¹ (camera frame).

TRIAD (Black 1964; Shuster & Oh 1981): the triads t1 = b1, t2 = (b1 × b2)/|b1 × b2|, t3 = t1 × t2 and the same
from r1, r2 give A = [t_b][t_r]ᵀ. The first (anchor) star fixes two axes exactly; the second only the rotation
about the first. Its first-order covariance, for σ1, σ2 rad per axis on b1, b2 (the form of Shuster & Oh 1981,
derived here by linearising the triads; tests/test_star_attitude.py checks it by Monte Carlo), is
P = σ1² I + |b1×b2|⁻² [σ1² (b1·b2)(b1 b2ᵀ + b2 b1ᵀ) + (σ2² − σ1²) b1 b1ᵀ].
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from math import atan2, cos, sin, sqrt

import numpy as np
from scipy.linalg.lapack import dgesdd as _dgesdd  # loaded with scipy.spatial (the catalogue's k-d tree) anyway

ARCSEC = np.pi / (180.0 * 3600.0)


@dataclass
class AttitudeSolution:
    """An attitude estimate: matrix, quaternion and error covariance."""

    matrix: np.ndarray
    """(3, 3) camera-from-ICRS attitude matrix A."""
    covariance: np.ndarray
    """(3, 3) covariance of the attitude error δθ (rad², camera frame)."""
    n_stars: int
    observed: np.ndarray = field(repr=False)
    """(N, 3) the stars' directions b_i (camera frame) given to the solver."""
    reference: np.ndarray = field(repr=False)
    """(N, 3) their catalogue vectors r_i (ICRS)."""

    @cached_property
    def residuals(self) -> np.ndarray:
        """(N,) angle (rad) between each b_i and A r_i (computed when first read)."""
        return residuals(self.matrix, self.observed, self.reference)

    @property
    def quaternion(self) -> np.ndarray:
        """(qw, qx, qy, qz) of A (module docstring)."""
        return quaternion_from_matrix(self.matrix)


def skew(v: np.ndarray) -> np.ndarray:
    """[v×], the cross-product matrix."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _xyzw_from_rotation(A: np.ndarray) -> tuple[float, float, float, float]:
    """Unit quaternion (x, y, z, w) of a rotation matrix by Markley's method (Markley 2008, "Unit Quaternion
    from Rotation Matrix"): of the four candidates, the one built on the largest of A11, A22, A33 and tr A, then
    normalised. A matrix that is not orthogonal to 1e-12 is first replaced by the nearest rotation, U Vᵀ from
    its SVD (the orthogonal Procrustes solution); a matrix with det A <= 0 is no rotation (ValueError)."""
    A = np.asarray(A, dtype=float)
    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = A.tolist()
    det = m00 * (m11 * m22 - m12 * m21) - m01 * (m10 * m22 - m12 * m20) + m02 * (m10 * m21 - m11 * m20)
    if not det > 0.0:
        raise ValueError(f"not a rotation matrix (det {det}): {A.tolist()}")
    if not np.all(np.abs(A @ A.T - _EYE) <= _ORTHOGONAL_TOL):
        U, _, Vt = np.linalg.svd(A)
        (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = (U @ Vt).tolist()
    tr = m00 + m11 + m22
    largest = max(m00, m11, m22, tr)
    if largest == m00:
        q = (1.0 - tr + 2.0 * m00, m10 + m01, m20 + m02, m21 - m12)
    elif largest == m11:
        q = (m10 + m01, 1.0 - tr + 2.0 * m11, m21 + m12, m02 - m20)
    elif largest == m22:
        q = (m20 + m02, m21 + m12, 1.0 - tr + 2.0 * m22, m10 - m01)
    else:
        q = (m21 - m12, m02 - m20, m10 - m01, 1.0 + tr)
    n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return q[0] / n, q[1] / n, q[2] / n, q[3] / n


_EYE = np.eye(3)
_ORTHOGONAL_TOL = 1e-12 + 1e-5 * _EYE
"""|A Aᵀ − I| within 1e-12 off the diagonal (1e-5 relative on it): A is taken as orthogonal."""


def _matrix_from_xyzw(x: float, y: float, z: float, w: float) -> np.ndarray:
    """Rotation matrix of the unit quaternion (x, y, z, w) (w the scalar part)."""
    x2, y2, z2, w2 = x * x, y * y, z * z, w * w
    xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
    return np.array(
        [
            [x2 - y2 - z2 + w2, 2.0 * (xy - zw), 2.0 * (xz + yw)],
            [2.0 * (xy + zw), -x2 + y2 - z2 + w2, 2.0 * (yz - xw)],
            [2.0 * (xz - yw), 2.0 * (yz + xw), -x2 - y2 + z2 + w2],
        ]
    )


def _rotvec_from_xyzw(x: float, y: float, z: float, w: float) -> np.ndarray:
    """Rotation vector θ n of the unit quaternion (x, y, z, w): θ = 2 atan2(|(x, y, z)|, |w|) and
    θ n = (θ / sin(θ/2)) (x, y, z), by its series 2 + θ²/12 + 7θ⁴/2880 for θ <= 1e-3."""
    if w < 0.0:
        x, y, z, w = -x, -y, -z, -w
    angle = 2.0 * atan2(sqrt(x * x + y * y + z * z), w)
    if angle <= 1e-3:
        a2 = angle * angle
        scale = 2.0 + a2 / 12.0 + 7.0 * a2 * a2 / 2880.0
    else:
        scale = angle / sin(angle / 2.0)
    return np.array([scale * x, scale * y, scale * z])


def quaternion_from_matrix(A: np.ndarray) -> np.ndarray:
    """(qw, qx, qy, qz), qw >= 0, of a rotation matrix (module docstring)."""
    x, y, z, w = _xyzw_from_rotation(A)
    return np.array([w, x, y, z]) if w >= 0 else np.array([-w, -x, -y, -z])


def matrix_from_quaternion(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a scalar-first quaternion (normalised first)."""
    w, x, y, z = np.asarray(q, dtype=float).tolist()
    n = sqrt(x * x + y * y + z * z + w * w)
    return _matrix_from_xyzw(x / n, y / n, z / n, w / n)


def rotation_matrix(rotvec: np.ndarray) -> np.ndarray:
    """exp([θ×]): the matrix of the rotation by the rotation vector θ (rad), through its unit quaternion
    (sin(|θ|/2) θ/|θ|, cos(|θ|/2)), the ratio by its series 1/2 − |θ|²/48 + |θ|⁴/3840 for |θ| <= 1e-3."""
    x, y, z = np.asarray(rotvec, dtype=float).tolist()
    angle = sqrt(x * x + y * y + z * z)
    if angle <= 1e-3:
        a2 = angle * angle
        scale = 0.5 - a2 / 48.0 + a2 * a2 / 3840.0
    else:
        scale = sin(angle / 2.0) / angle
    return _matrix_from_xyzw(scale * x, scale * y, scale * z, cos(angle / 2.0))


def error_angle(A_est: np.ndarray, A_true: np.ndarray) -> float:
    """Angle (rad) of the rotation between two attitudes, arccos((tr(Â Aᵀ) − 1)/2), computed stably (from
    the quaternion of Â Aᵀ: 2 atan2(|q_v|, |q_w|))."""
    x, y, z, w = _xyzw_from_rotation(np.asarray(A_est) @ np.asarray(A_true).T)
    return 2.0 * atan2(sqrt(x * x + y * y + z * z), abs(w))


def error_vector(A_est: np.ndarray, A_true: np.ndarray) -> np.ndarray:
    """Attitude error δθ (rad, camera frame) with Â = exp(−[δθ×]) A (module docstring)."""
    return -_rotvec_from_xyzw(*_xyzw_from_rotation(np.asarray(A_est) @ np.asarray(A_true).T))


def error_components(A_est: np.ndarray, A_true: np.ndarray) -> tuple[float, float]:
    """(cross-boresight, roll) parts of the attitude error (rad): |(δθ_x, δθ_y)| — the pointing error of the
    boresight — and |δθ_z|, the rotation about it (δθ in the camera frame, :func:`error_vector`)."""
    e = error_vector(A_est, A_true)
    return float(np.hypot(e[0], e[1])), float(abs(e[2]))


def davenport_quaternion(b: np.ndarray, r: np.ndarray, w: np.ndarray | None = None) -> np.ndarray:
    """Davenport's q-method for Wahba's problem, an independent check of :func:`wahba_matrix`. With
    B = Σ w b rᵀ, σ = tr B and z = (B23 − B32, B31 − B13, B12 − B21), the optimum is the eigenvector of the
    largest eigenvalue of K = [[σ, zᵀ], [z, B + Bᵀ − σ I]] (Davenport 1968; Markley & Crassidis 2014, §5.3),
    a quaternion of the attitude-matrix convention A = (q0² − |q|²) I + 2 q qᵀ − 2 q0 [q×], which is the
    conjugate of the rotation quaternion used here: its vector part is negated on return, giving
    (qw, qx, qy, qz) with A = R(q), qw >= 0."""
    b, r = np.asarray(b, dtype=float), np.asarray(r, dtype=float)
    B = b.T @ r if w is None else (b * np.asarray(w, dtype=float)[:, None]).T @ r
    sigma = np.trace(B)
    z = np.array([B[1, 2] - B[2, 1], B[2, 0] - B[0, 2], B[0, 1] - B[1, 0]])
    K = np.zeros((4, 4))
    K[0, 0], K[0, 1:], K[1:, 0] = sigma, z, z
    K[1:, 1:] = B + B.T - sigma * np.eye(3)
    _, V = np.linalg.eigh(K)
    q = V[:, -1]
    q = np.array([q[0], -q[1], -q[2], -q[3]])
    return q if q[0] >= 0 else -q


def residuals(A: np.ndarray, b: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Angles (rad) between observed directions b (N, 3) and the predicted A r (N, 3)."""
    d = np.asarray(b) - np.asarray(r) @ np.asarray(A).T
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    return 2.0 * np.arcsin(np.minimum(np.sqrt(x * x + y * y + z * z) / 2.0, 1.0))  # |d| = 2 sin(angle/2)


def _svd(B: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """U, S, Vᵀ of a 3 × 3 matrix by LAPACK's dgesdd, as np.linalg.svd computes it, called directly: the
    lost-in-space identification solves Wahba's problem several times a frame, and numpy's wrapper (type and
    error-state handling) cost more than the decomposition. np.linalg.svd where dgesdd reports a failure
    (it then raises LinAlgError)."""
    U, S, Vt, info = _dgesdd(B)
    return (U, S, Vt) if info == 0 else np.linalg.svd(B)


def wahba_matrix(b: np.ndarray, r: np.ndarray, w: np.ndarray | None = None) -> np.ndarray:
    """The A minimising Σ w_i |b_i − A r_i|² (SVD solution, module docstring); b, r (N, 3), N >= 2."""
    b, r = np.asarray(b, dtype=float), np.asarray(r, dtype=float)
    B = b.T @ r if w is None else (b * np.asarray(w, dtype=float)[:, None]).T @ r
    U, _, Vt = _svd(B)
    A = U @ Vt
    (a00, a01, a02), (a10, a11, a12), (a20, a21, a22) = A.tolist()  # det A = ±1
    if a00 * (a11 * a22 - a12 * a21) - a01 * (a10 * a22 - a12 * a20) + a02 * (a10 * a21 - a11 * a20) < 0:
        A = (U * np.array([1.0, 1.0, -1.0])) @ Vt  # the proper rotation: flip the smallest singular value's axis
    return A


def wahba(b: np.ndarray, r: np.ndarray, sigma: float | np.ndarray) -> AttitudeSolution:
    """Least-squares attitude over all stars with per-star angular noise σ (rad, scalar or (N,)); the
    covariance is the QUEST measurement model's (Σ (I − b bᵀ)/σ²)⁻¹ (module docstring)."""
    b, r = np.asarray(b, dtype=float), np.asarray(r, dtype=float)
    if len(b) < 2:
        raise ValueError("Wahba's problem needs at least two stars")
    s2 = np.broadcast_to(np.asarray(sigma, dtype=float) ** 2, (len(b),))
    A = wahba_matrix(b, r, 1.0 / s2)
    F = np.einsum("n,nij->ij", 1.0 / s2, np.eye(3)[None] - b[:, :, None] * b[:, None, :])
    return AttitudeSolution(A, np.linalg.inv(F), len(b), b, r)


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b of two 3-vectors (np.cross's arithmetic without its per-call overhead)."""
    (a0, a1, a2), (b0, b1, b2) = np.asarray(a, dtype=float).tolist(), np.asarray(b, dtype=float).tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def triad_matrix(b1: np.ndarray, b2: np.ndarray, r1: np.ndarray, r2: np.ndarray) -> np.ndarray:
    """TRIAD attitude matrix, anchored on the first star (module docstring)."""

    def triad(v1: np.ndarray, v2: np.ndarray) -> np.ndarray:
        t1 = v1 / np.linalg.norm(v1)
        t2 = cross(v1, v2)
        t2 = t2 / np.linalg.norm(t2)
        return np.column_stack([t1, t2, cross(t1, t2)])

    return triad(np.asarray(b1, float), np.asarray(b2, float)) @ triad(np.asarray(r1, float), np.asarray(r2, float)).T


def triad(
    b: np.ndarray, r: np.ndarray, sigma: float | np.ndarray, pair: tuple[int, int] | None = None
) -> AttitudeSolution:
    """TRIAD from two of the stars (b, r (N, 3), N >= 2), as the paper computes the attitude. ``pair`` picks
    them (anchor first); by default the pair with the largest separation, whose |b1 × b2| is largest, anchored
    on the first star of the list. The residuals are of all N stars against the TRIAD attitude."""
    b, r = np.asarray(b, dtype=float), np.asarray(r, dtype=float)
    if len(b) < 2:
        raise ValueError("TRIAD needs two stars")
    if pair is None:
        i = 0
        j = int(np.argmin(b[1:] @ b[0])) + 1
    else:
        i, j = pair
    s = np.broadcast_to(np.asarray(sigma, dtype=float), (len(b),))
    A = triad_matrix(b[i], b[j], r[i], r[j])
    b1, b2 = b[i], b[j]
    c = cross(b1, b2)
    P = s[i] ** 2 * np.eye(3) + (
        s[i] ** 2 * (b1 @ b2) * (np.outer(b1, b2) + np.outer(b2, b1)) + (s[j] ** 2 - s[i] ** 2) * np.outer(b1, b1)
    ) / (c @ c)
    return AttitudeSolution(A, P, 2, b, r)
