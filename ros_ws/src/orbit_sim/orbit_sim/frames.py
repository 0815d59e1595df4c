"""Inertial (ECI), Earth-fixed (ECEF), geodetic and local ENU frames.

Simplified Earth orientation: ECI is taken as a true-of-date inertial frame and ECEF is obtained by a
single rotation about the common z axis by the Earth rotation angle theta(t) = theta0 + OMEGA_EARTH t.
Precession, nutation, polar motion and UT1-UTC are deliberately ignored: truth, sensor and filters all
use this same model, so it is self-consistent, which is all the simulation needs.

Array convention: positions are (3,) or (m, 3), states [x y z vx vy vz] are (6,) or (m, 6), one per
row. The time ``t`` may be a scalar or an array (m,) giving one epoch per row.
The ENU frame follows paper 000 eqs. 8-10, except that the station is placed on the WGS84 ellipsoid
(geodetic latitude) instead of the paper's sphere of radius Re + h.
"""
from __future__ import annotations

import numpy as np

from .constants import OMEGA_EARTH, R_EARTH, WGS84_E2, WGS84_F


def earth_rotation_angle(t: float | np.ndarray, theta0: float = 0.0) -> float | np.ndarray:
    """Angle [rad] from the ECI x axis to the ECEF x axis at time t [s]: theta0 + OMEGA_EARTH t."""
    return theta0 + OMEGA_EARTH * np.asarray(t, dtype=float)


def _rotate_z(v: np.ndarray, angle: float | np.ndarray) -> np.ndarray:
    """Components of v in a frame rotated by +angle about z (the passive rotation R3(angle) v)."""
    v = np.asarray(v, dtype=float)
    c = np.cos(angle)
    s = np.sin(angle)
    out = np.empty_like(v)
    out[..., 0] = c * v[..., 0] + s * v[..., 1]
    out[..., 1] = -s * v[..., 0] + c * v[..., 1]
    out[..., 2] = v[..., 2]
    return out


def eci_to_ecef(r_eci: np.ndarray, t: float | np.ndarray, theta0: float = 0.0) -> np.ndarray:
    """ECI position(s) -> ECEF position(s) at time t."""
    return _rotate_z(r_eci, earth_rotation_angle(t, theta0))


def ecef_to_eci(r_ecef: np.ndarray, t: float | np.ndarray, theta0: float = 0.0) -> np.ndarray:
    """ECEF position(s) -> ECI position(s) at time t."""
    return _rotate_z(r_ecef, -earth_rotation_angle(t, theta0))


def eci_to_ecef_state(state: np.ndarray, t: float | np.ndarray, theta0: float = 0.0) -> np.ndarray:
    """ECI state(s) -> ECEF state(s): v_ecef = R (v_eci - omega x r_eci)."""
    state = np.asarray(state, dtype=float)
    theta = earth_rotation_angle(t, theta0)
    v_rel = state[..., 3:6].copy()
    v_rel[..., 0] += OMEGA_EARTH * state[..., 1]
    v_rel[..., 1] -= OMEGA_EARTH * state[..., 0]
    return np.concatenate((_rotate_z(state[..., 0:3], theta), _rotate_z(v_rel, theta)), axis=-1)


def ecef_to_eci_state(state: np.ndarray, t: float | np.ndarray, theta0: float = 0.0) -> np.ndarray:
    """ECEF state(s) -> ECI state(s): v_eci = R^T v_ecef + omega x r_eci."""
    state = np.asarray(state, dtype=float)
    theta = earth_rotation_angle(t, theta0)
    r_eci = _rotate_z(state[..., 0:3], -theta)
    v_eci = _rotate_z(state[..., 3:6], -theta)
    v_eci[..., 0] -= OMEGA_EARTH * r_eci[..., 1]
    v_eci[..., 1] += OMEGA_EARTH * r_eci[..., 0]
    return np.concatenate((r_eci, v_eci), axis=-1)


def geodetic_to_ecef(lat_rad: float, lon_rad: float, h_m: float) -> np.ndarray:
    """WGS84 geodetic latitude, longitude [rad] and ellipsoidal height [m] -> ECEF position (3,)."""
    sin_lat = np.sin(lat_rad)
    n = R_EARTH / np.sqrt(1.0 - WGS84_E2 * sin_lat * sin_lat)
    rho = (n + h_m) * np.cos(lat_rad)
    return np.array([rho * np.cos(lon_rad), rho * np.sin(lon_rad),
                     (n * (1.0 - WGS84_E2) + h_m) * sin_lat])


def ecef_to_geodetic(r_ecef: np.ndarray, iterations: int = 4) -> tuple[float, float, float]:
    """ECEF position (3,) -> WGS84 (lat [rad], lon [rad], h [m]) by Bowring's iteration.

    Bowring's parametric-latitude iteration converges to well below a millimetre in 2-3 steps for
    points from the Earth's surface to LEO; the height formula is valid at the poles too.
    """
    x, y, z = np.asarray(r_ecef, dtype=float)
    b = R_EARTH * (1.0 - WGS84_F)
    ep2 = WGS84_E2 / (1.0 - WGS84_E2)
    p = np.hypot(x, y)
    beta = np.arctan2(z, (1.0 - WGS84_F) * p)
    for _ in range(iterations):
        lat = np.arctan2(z + ep2 * b * np.sin(beta) ** 3, p - WGS84_E2 * R_EARTH * np.cos(beta) ** 3)
        beta = np.arctan2((1.0 - WGS84_F) * np.sin(lat), np.cos(lat))
    sin_lat = np.sin(lat)
    n = R_EARTH / np.sqrt(1.0 - WGS84_E2 * sin_lat * sin_lat)
    h = p * np.cos(lat) + (z + WGS84_E2 * n * sin_lat) * sin_lat - n
    return float(lat), float(np.arctan2(y, x)), float(h)


def enu_rotation(lat_rad: float, lon_rad: float) -> np.ndarray:
    """ECEF -> ENU rotation (paper eq. 9): rows are the East, North, Up unit vectors in ECEF.

    enu = enu_rotation(lat, lon) @ (r_ecef - station_ecef)   (paper eq. 10).
    """
    sl, cl = np.sin(lat_rad), np.cos(lat_rad)
    so, co = np.sin(lon_rad), np.cos(lon_rad)
    return np.array([[-so, co, 0.0],
                     [-sl * co, -sl * so, cl],
                     [cl * co, cl * so, sl]])
