"""Classical orbital elements <-> Cartesian state, and Kepler's equation (elliptic orbits only).

Angles are in radians; a in metres. Used to build the initial state from the CHAMP elements of
paper 000, Table 1. Degenerate cases (e = 0 or i = 0, where the node or perigee is undefined) are
not handled specially: the elements must be well defined, as they are for CHAMP.
"""

from __future__ import annotations

import numpy as np

from .constants import MU_EARTH


def solve_kepler(M: float | np.ndarray, e: float, tol: float = 1e-14, max_iter: int = 50) -> float | np.ndarray:
    """Eccentric anomaly E solving M = E - e sin E (0 <= e < 1) by Newton's method.

    M is reduced to [-pi, pi) and Newton starts from Danby's E0 = M + 0.85 e sign(sin M), which
    converges for every M and e < 1; the removed multiple of 2 pi is added back to E.
    """
    M = np.asarray(M, dtype=float)
    turns = np.floor((M + np.pi) / (2.0 * np.pi)) * 2.0 * np.pi
    m = M - turns
    E = m + 0.85 * e * np.sign(np.sin(m))
    for _ in range(max_iter):
        dE = (E - e * np.sin(E) - m) / (1.0 - e * np.cos(E))
        E = E - dE
        if np.all(np.abs(dE) < tol):
            break
    E = E + turns
    return float(E) if E.ndim == 0 else E


def _perifocal_to_eci(i: float, raan: float, argp: float) -> np.ndarray:
    """Rotation matrix R3(-raan) R1(-i) R3(-argp): perifocal (P, Q, W) columns expressed in ECI."""
    co, so = np.cos(raan), np.sin(raan)
    cw, sw = np.cos(argp), np.sin(argp)
    ci, si = np.cos(i), np.sin(i)
    return np.array(
        [
            [co * cw - so * sw * ci, -co * sw - so * cw * ci, so * si],
            [so * cw + co * sw * ci, -so * sw + co * cw * ci, -co * si],
            [sw * si, cw * si, ci],
        ]
    )


def kepler_to_cartesian(
    a: float, e: float, i: float, raan: float, argp: float, M: float, mu: float = MU_EARTH
) -> np.ndarray:
    """Classical elements -> inertial state [x y z vx vy vz] (6,) in m and m/s."""
    E = solve_kepler(M, e)
    cE, sE = np.cos(E), np.sin(E)
    b_over_a = np.sqrt(1.0 - e * e)
    r_pf = a * np.array([cE - e, b_over_a * sE, 0.0])
    v_pf = np.sqrt(mu * a) / (a * (1.0 - e * cE)) * np.array([-sE, b_over_a * cE, 0.0])
    rot = _perifocal_to_eci(i, raan, argp)
    return np.concatenate((rot @ r_pf, rot @ v_pf))


def cartesian_to_kepler(state: np.ndarray, mu: float = MU_EARTH) -> dict[str, float]:
    """Inertial state (6,) -> dict(a, e, i, raan, argp, M); raan, argp, M in [0, 2 pi)."""
    r = np.asarray(state[0:3], dtype=float)
    v = np.asarray(state[3:6], dtype=float)
    rn = np.linalg.norm(r)
    h = np.cross(r, v)
    node = np.array([-h[1], h[0], 0.0])
    e_vec = np.cross(v, h) / mu - r / rn
    e = float(np.linalg.norm(e_vec))
    a = 1.0 / (2.0 / rn - float(v @ v) / mu)
    i = float(np.arccos(h[2] / np.linalg.norm(h)))
    raan = float(np.arctan2(node[1], node[0]))
    # Angles measured in the orbit plane from the node line, sign from the angular momentum.
    h_hat = h / np.linalg.norm(h)
    n_hat = node / np.linalg.norm(node)
    argp = float(np.arctan2(np.cross(n_hat, e_vec) @ h_hat, n_hat @ e_vec))
    nu = float(np.arctan2(np.cross(e_vec, r) @ h_hat, e_vec @ r))
    E = 2.0 * np.arctan2(np.sqrt(1.0 - e) * np.sin(nu / 2.0), np.sqrt(1.0 + e) * np.cos(nu / 2.0))
    M = float(E - e * np.sin(E))
    two_pi = 2.0 * np.pi
    return dict(a=float(a), e=e, i=i, raan=raan % two_pi, argp=argp % two_pi, M=M % two_pi)
