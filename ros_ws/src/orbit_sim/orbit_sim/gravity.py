"""Two-body + J2 gravitational acceleration in an inertial frame (paper 000, eqs. 4-7).

With A = J2 Re^2 / 2 (eq. 6):
    a_x = mu [-x/r^3 + A (15 x z^2 / r^7 - 3 x / r^5)]      (a_y likewise with y)
    a_z = mu [-z/r^3 + A (15 z^3 / r^7 - 9 z / r^5)]
Writing a_i = -mu r_i / r^3 + k r_i f_i with k = mu A, f_x = f_y = 15 z^2/r^7 - 3/r^5 and
f_z = 15 z^2/r^7 - 9/r^5 gives the compact form used for the value and its Jacobian.
"""

from __future__ import annotations

import math

import numpy as np

from .constants import J2_EARTH, MU_EARTH, R_EARTH

_C = np.array([3.0, 3.0, 9.0])
"""The r^-5 coefficients of f_x, f_y, f_z."""


def acceleration(r: np.ndarray, mu: float = MU_EARTH, j2: float = J2_EARTH, re: float = R_EARTH) -> np.ndarray:
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


def gravity_gradient(x: float, y: float, z: float, mu: float, j2: float, re: float) -> np.ndarray:
    """d a / d r (3, 3) of the two-body + J2 acceleration (paper eq. 6) at one position, in Python floats
    (the EKF calls it every step).

    With k = mu J2 Re^2 / 2, a_i = r_i f_i, f_x = f_y = k (15 z^2/r^7 - 3/r^5) - mu/r^3 and
    f_z = k (15 z^2/r^7 - 9/r^5) - mu/r^3:  G_ij = f_i delta_ij + r_i d f_i / d r_j. Symmetric.
    """
    k = 0.5 * mu * j2 * re * re
    r2 = x * x + y * y + z * z
    ir2 = 1.0 / r2
    ir3 = ir2 / math.sqrt(r2)
    ir5 = ir3 * ir2
    ir7 = ir5 * ir2
    zz = z * z
    f_xy = k * (15.0 * zz * ir7 - 3.0 * ir5) - mu * ir3
    f_z = f_xy - 6.0 * k * ir5
    # d f_i / d r = g_i r + (30 k z / r^7) e_z
    g_xy = 3.0 * mu * ir5 + k * (15.0 - 105.0 * zz * ir2) * ir7
    g_z = g_xy + 30.0 * k * ir7
    xz = x * g_z * z
    yz = y * g_z * z
    return np.array(
        [
            [f_xy + g_xy * x * x, g_xy * x * y, xz],
            [g_xy * x * y, f_xy + g_xy * y * y, yz],
            [xz, yz, f_z + g_z * zz + 30.0 * k * ir7 * zz],
        ]
    )


def acceleration_jacobian(r: np.ndarray, mu: float = MU_EARTH, j2: float = J2_EARTH, re: float = R_EARTH) -> np.ndarray:
    """Analytic d a / d r at a single position r (3,), shape (3, 3) (see ``gravity_gradient``)."""
    return gravity_gradient(float(r[0]), float(r[1]), float(r[2]), mu, j2, re)


def state_derivative(
    t: float, y: np.ndarray, mu: float = MU_EARTH, j2: float = J2_EARTH, re: float = R_EARTH
) -> np.ndarray:
    """d/dt [x y z vx vy vz] = [v, a(r)] (eq. 7 with w = 0); signature fits scipy's solve_ivp."""
    return np.concatenate((y[3:6], acceleration(y[0:3], mu, j2, re)))
