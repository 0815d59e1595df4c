"""Two-body + J2 gravitational acceleration in an inertial frame (paper 000, eqs. 4-7).

With A = J2 Re^2 / 2 (eq. 6):
    a_x = mu [-x/r^3 + A (15 x z^2 / r^7 - 3 x / r^5)]      (a_y likewise with y)
    a_z = mu [-z/r^3 + A (15 z^3 / r^7 - 9 z / r^5)]
Writing a_i = -mu r_i / r^3 + k r_i f_i with k = mu A, f_x = f_y = 15 z^2/r^7 - 3/r^5 and
f_z = 15 z^2/r^7 - 9/r^5 gives the compact form used for the value and its Jacobian.
"""
from __future__ import annotations

import numpy as np

from .constants import J2_EARTH, MU_EARTH, R_EARTH

_C = np.array([3.0, 3.0, 9.0])
"""The r^-5 coefficients of f_x, f_y, f_z."""


def acceleration(r: np.ndarray, mu: float = MU_EARTH, j2: float = J2_EARTH,
                 re: float = R_EARTH) -> np.ndarray:
    """Acceleration [m/s^2] at position r [m], shape (3,) or (m, 3) (one position per row).

    ``j2=0`` gives pure two-body motion (eq. 7 without the perturbation terms w).
    """
    r = np.asarray(r, dtype=float)
    r2 = np.sum(r * r, axis=-1, keepdims=True)
    inv_r = 1.0 / np.sqrt(r2)
    inv_r2 = inv_r * inv_r
    inv_r3 = inv_r2 * inv_r
    inv_r5 = inv_r3 * inv_r2
    z2 = r[..., 2:3] ** 2
    k = mu * 0.5 * j2 * re * re
    f = 15.0 * z2 * inv_r5 * inv_r2 - _C * inv_r5
    return r * (k * f - mu * inv_r3)


def acceleration_jacobian(r: np.ndarray, mu: float = MU_EARTH, j2: float = J2_EARTH,
                          re: float = R_EARTH) -> np.ndarray:
    """Analytic d a / d r at a single position r (3,), shape (3, 3).

    Two-body part: -mu (I / r^3 - 3 r r^T / r^5).
    J2 part: k (diag(f) + r (grad f_i)^T) with
    grad f_i = -105 z^2 r / r^9 + 5 c_i r / r^7 + 30 z e_z / r^7.
    """
    r = np.asarray(r, dtype=float)
    rn2 = float(r @ r)
    rn = np.sqrt(rn2)
    inv_r3 = 1.0 / (rn2 * rn)
    inv_r5 = inv_r3 / rn2
    inv_r7 = inv_r5 / rn2
    inv_r9 = inv_r7 / rn2
    z = r[2]
    k = mu * 0.5 * j2 * re * re
    two_body = -mu * (np.eye(3) * inv_r3 - 3.0 * np.outer(r, r) * inv_r5)
    f = 15.0 * z * z * inv_r7 - _C * inv_r5
    grad_f = np.outer(5.0 * _C * inv_r7 - 105.0 * z * z * inv_r9, r)
    grad_f[:, 2] += 30.0 * z * inv_r7
    return two_body + k * (np.diag(f) + r[:, None] * grad_f)


def state_derivative(t: float, y: np.ndarray, mu: float = MU_EARTH, j2: float = J2_EARTH,
                     re: float = R_EARTH) -> np.ndarray:
    """d/dt [x y z vx vy vz] = [v, a(r)] (eq. 7 with w = 0); signature fits scipy's solve_ivp."""
    return np.concatenate((y[3:6], acceleration(y[0:3], mu, j2, re)))
