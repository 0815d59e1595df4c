"""Hill / Clohessy-Wiltshire relative motion about a circular chief orbit, internal LVLH convention.

State [x y z vx vy vz] with x radial, y along-track, z orbit normal (see ``relative``). The equations
    x'' - 2 n y' - 3 n^2 x = 0,    y'' + 2 n x' = 0,    z'' + n^2 z = 0
are the standard CW equations (paper 004's print of its eq. 4 is garbled). Paper 001's eq. 2
(x'' + 2 w y' = 0, y'' - 2 w x' - 3 w^2 y = 0, z'' + w^2 z = 0) is the same system written in its own
axes (X along-track, Y radial, Z = -normal): convert states with ``relative.to_convention``.
"""

from __future__ import annotations

import numpy as np


def cw_matrix(n: float) -> np.ndarray:
    """Continuous-time CW system matrix A (6, 6): d/dt [r, v] = A [r, v], n the chief's mean motion [rad/s]."""
    A = np.zeros((6, 6))
    A[0:3, 3:6] = np.eye(3)
    A[3, 0] = 3.0 * n * n
    A[3, 4] = 2.0 * n
    A[4, 3] = -2.0 * n
    A[5, 2] = -n * n
    return A


def cw_stm(n: float, dt: float | np.ndarray) -> np.ndarray:
    """Exact CW state-transition matrix expm(A dt): (6, 6) for a scalar dt, (K, 6, 6) for dt of shape (K,)."""
    t = np.asarray(dt, dtype=float)
    s = np.sin(n * t)
    c = np.cos(n * t)
    nt = n * t
    P = np.zeros(t.shape + (6, 6))
    P[..., 0, 0] = 4.0 - 3.0 * c
    P[..., 0, 3] = s / n
    P[..., 0, 4] = 2.0 * (1.0 - c) / n
    P[..., 1, 0] = 6.0 * (s - nt)
    P[..., 1, 1] = 1.0
    P[..., 1, 3] = -2.0 * (1.0 - c) / n
    P[..., 1, 4] = (4.0 * s - 3.0 * nt) / n
    P[..., 2, 2] = c
    P[..., 2, 5] = s / n
    P[..., 3, 0] = 3.0 * n * s
    P[..., 3, 3] = c
    P[..., 3, 4] = 2.0 * s
    P[..., 4, 0] = -6.0 * n * (1.0 - c)
    P[..., 4, 3] = -2.0 * s
    P[..., 4, 4] = 4.0 * c - 3.0
    P[..., 5, 2] = -n * s
    P[..., 5, 5] = c
    return P


def cw_propagate(rel0: np.ndarray, times: np.ndarray, n: float) -> np.ndarray:
    """Exact solution of the CW equations from rel0 (6,), given at times[0], sampled at ``times``: (K, 6).

    This is the "Hill truth" mode (paper 001's setup as printed): the closed-form STM is the exact
    solution of the linear equations, so no numerical integration error enters.
    """
    times = np.asarray(times, dtype=float)
    return np.einsum("kij,j->ki", cw_stm(n, times - times[0]), np.asarray(rel0, dtype=float))
