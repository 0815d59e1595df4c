"""Zonal geopotential to degree n (J2 .. Jn) and an exponential atmosphere's drag: the higher-fidelity truth a
purely kinematic filter is judged against (paper 002's GRACE pair).

Zonal gravity (Vallado, "Fundamentals of Astrodynamics and Applications", 4th ed., section 8.6): with
u = z / r and the Legendre polynomials P_n, the potential V = mu/r [1 - sum_n J_n (Re/r)^n P_n(u)] gives

    a = -mu r_hat / r^2 + sum_n mu J_n Re^n / r^(n+2) [(n + 1) P_n(u) r_hat - P_n'(u) (z_hat - u r_hat)]

(for n = 2 this is paper 000's eq. 6). P_n and P_n' follow Bonnet's recurrence and
P'_(n+1) = P'_(n-1) + (2n + 1) P_n, both regular at the poles.

Drag: a = -1/2 B rho(h) |v_rel| v_rel, v_rel = v - omega_E x r (a co-rotating atmosphere), B = C_d A / m.
rho(h) is the piecewise-exponential CIRA-72 fit of Vallado's Table 8-4 above the geodetic height h
(h from the WGS84 ellipsoid's radius at the geocentric latitude: the flattening alone moves h by 21 km).
"""

from __future__ import annotations

import math
from bisect import bisect_right

import numpy as np

from .constants import OMEGA_EARTH, R_EARTH, WGS84_F

ZONALS = {2: 1.08262668355e-3, 3: -2.53265648533e-6, 4: -1.61962159137e-6, 5: -2.27296082869e-7, 6: 5.40681239107e-7}
"""Unnormalised zonal coefficients J_2 .. J_6 of EGM96 (J_n = -sqrt(2n + 1) C_n0 normalised)."""

_ATMOSPHERE = np.array(
    [  # base height [km], base density [kg/m^3], scale height [km] (Vallado Table 8-4)
        [150.0, 2.070e-9, 22.523],
        [180.0, 5.464e-10, 29.740],
        [200.0, 2.789e-10, 37.105],
        [250.0, 7.248e-11, 45.546],
        [300.0, 2.418e-11, 53.628],
        [350.0, 9.518e-12, 53.298],
        [400.0, 3.725e-12, 58.515],
        [450.0, 1.585e-12, 60.828],
        [500.0, 6.967e-13, 63.822],
        [600.0, 1.454e-13, 71.835],
        [700.0, 3.614e-14, 88.667],
        [800.0, 1.170e-14, 124.64],
        [900.0, 5.245e-15, 181.05],
        [1000.0, 3.019e-15, 268.00],
    ]
)


def legendre(u: np.ndarray, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """P_n(u) and P_n'(u) for n = 0 .. degree, each (degree + 1, *u.shape)."""
    u = np.asarray(u, dtype=float)
    P = np.empty((degree + 1,) + u.shape)
    dP = np.empty_like(P)
    P[0], dP[0] = 1.0, 0.0
    if degree >= 1:
        P[1], dP[1] = u, 1.0
    for n in range(1, degree):
        P[n + 1] = ((2 * n + 1) * u * P[n] - n * P[n - 1]) / (n + 1)
        dP[n + 1] = dP[n - 1] + (2 * n + 1) * P[n]
    return P, dP


def zonal_acceleration(r: np.ndarray, mu: float, re: float, zonals: dict[int, float]) -> np.ndarray:
    """Gravity [m/s^2] of the central body plus the zonal terms ``zonals`` {n: J_n} at r (3,) or (m, 3)."""
    r = np.asarray(r, dtype=float)
    rn = np.linalg.norm(r, axis=-1, keepdims=True)
    r_hat = r / rn
    u = r_hat[..., 2:3]
    z_hat = np.zeros_like(r)
    z_hat[..., 2] = 1.0
    a = -mu * r_hat / rn**2
    if zonals:
        P, dP = legendre(u, max(zonals))
        for n, jn in zonals.items():
            scale = mu * jn * re**n / rn ** (n + 2)
            a = a + scale * ((n + 1) * P[n] * r_hat - dP[n] * (z_hat - u * r_hat))
    return a


def geodetic_height(r: np.ndarray, re: float = R_EARTH, f: float = WGS84_F) -> np.ndarray:
    """Height [m] above the ellipsoid's radius at the geocentric latitude (first order in f)."""
    r = np.asarray(r, dtype=float)
    rn = np.linalg.norm(r, axis=-1)
    sin_lat = r[..., 2] / rn
    return rn - re * (1.0 - f * sin_lat**2)


def density(h: np.ndarray) -> np.ndarray:
    """Atmospheric density [kg/m^3] at height h [m] (piecewise exponential; the lowest band below 150 km)."""
    h_km = np.asarray(h, dtype=float) / 1000.0
    band = np.clip(np.searchsorted(_ATMOSPHERE[:, 0], h_km, side="right") - 1, 0, len(_ATMOSPHERE) - 1)
    h0, rho0, scale = _ATMOSPHERE[band].T
    return rho0 * np.exp(-(h_km - h0) / scale)


def drag_acceleration(
    r: np.ndarray, v: np.ndarray, ballistic: float, rotation_rate: float = OMEGA_EARTH, re: float = R_EARTH
) -> np.ndarray:
    """-1/2 B rho |v_rel| v_rel [m/s^2], B = C_d A / m [m^2/kg], for one state (3,) or a batch (m, 3)."""
    r, v = np.asarray(r, dtype=float), np.asarray(v, dtype=float)
    omega = np.array([0.0, 0.0, rotation_rate])
    v_rel = v - np.cross(omega, r)
    speed = np.linalg.norm(v_rel, axis=-1, keepdims=True)
    rho = density(geodetic_height(r, re))[..., None]
    return -0.5 * ballistic * rho * speed * v_rel


# --- one state in Python floats ------------------------------------------------------------------------------
# The same arithmetic as the functions above for one state, without numpy's per-call cost on 3-vectors: the
# right-hand side of an orbit fit's variational equations evaluates them about a hundred thousand times a day
# (orbit_sim.orbit_fit). tests/test_orbit_fit.py compares them with the functions above.

_BAND_KM = _ATMOSPHERE[:, 0].tolist()
_BANDS = [tuple(row) for row in _ATMOSPHERE.tolist()]


def zonal_acceleration_xyz(
    x: float, y: float, z: float, mu: float, re: float, zonals: dict[int, float]
) -> tuple[float, float, float]:
    """:func:`zonal_acceleration` at one position (x, y, z) [m], in Python floats."""
    rn = math.sqrt(x * x + y * y + z * z)
    hx, hy, u = x / rn, y / rn, z / rn
    rn2 = rn**2
    ax, ay, az = -mu * hx / rn2, -mu * hy / rn2, -mu * u / rn2
    if zonals:
        degree = max(zonals)
        P, dP = [1.0, u], [0.0, 1.0]
        for n in range(1, degree):
            P.append(((2 * n + 1) * u * P[n] - n * P[n - 1]) / (n + 1))
            dP.append(dP[n - 1] + (2 * n + 1) * P[n])
        for n, jn in zonals.items():
            scale = mu * jn * re**n / rn ** (n + 2)
            radial, polar = (n + 1) * P[n], dP[n]
            ax = ax + scale * (radial * hx - polar * (0.0 - u * hx))
            ay = ay + scale * (radial * hy - polar * (0.0 - u * hy))
            az = az + scale * (radial * u - polar * (1.0 - u * u))
    return ax, ay, az


def drag_acceleration_xyz(
    x: float,
    y: float,
    z: float,
    vx: float,
    vy: float,
    vz: float,
    ballistic: float,
    rotation_rate: float = OMEGA_EARTH,
    re: float = R_EARTH,
    f: float = WGS84_F,
) -> tuple[float, float, float]:
    """:func:`drag_acceleration` of one state, in Python floats."""
    wx, wy, wz = vx + rotation_rate * y, vy - rotation_rate * x, vz  # v - omega x r, omega along z
    speed = math.sqrt(wx * wx + wy * wy + wz * wz)
    rn = math.sqrt(x * x + y * y + z * z)
    sin_lat = z / rn
    h_km = (rn - re * (1.0 - f * sin_lat**2)) / 1000.0
    h0, rho0, scale = _BANDS[min(max(bisect_right(_BAND_KM, h_km) - 1, 0), len(_BANDS) - 1)]
    k = -0.5 * ballistic * (rho0 * math.exp(-(h_km - h0) / scale)) * speed
    return k * wx, k * wy, k * wz
