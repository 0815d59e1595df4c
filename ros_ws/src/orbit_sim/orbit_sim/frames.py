"""Inertial (ECI), Earth-fixed (ECEF), geodetic and local ENU frames.

Simplified Earth orientation: ECI is taken as a true-of-date inertial frame and ECEF is obtained by a
single rotation about the common z axis by the Earth rotation angle theta(t) = theta0 + OMEGA_EARTH t.
Precession, nutation and polar motion over a run are deliberately ignored: truth, sensor and filters all
use this same model, so it is self-consistent, which is all the simulation needs.

On the calendar (a scenario with ``time.epoch``, orbit_sim.truth.build_earth), theta0 is the Greenwich mean
sidereal time of the epoch (IAU-82, :func:`gmst82`, of UT1 = UTC + ``earth.ut1_minus_utc_s``). The bench's
``eci`` is then TEME of the epoch (true equator, mean equinox: the frame of SGP4's output, orbit_sim.tle) and
ECEF the pseudo-Earth-fixed frame PEF, the standard TEME -> PEF rotation R3(GMST) (Vallado et al. 2006,
"Revisiting Spacetrack Report #3", AIAA 2006-6753, sec. on TEME). What the bench leaves out, and its size:
- TEME of date against TEME of the epoch: SGP4's output is read as one inertial frame over a run, in which the
  Earth turns at OMEGA_EARTH (7.292115e-5 rad/s, WGS84); TEME of date turns with the equinox's precession, and
  GMST runs at d(GMST)/dt = 7.2921158553e-5 rad/s, 8.55e-12 rad/s more. R3(theta0 + OMEGA_EARTH t) and
  TEME -> PEF = R3(GMST(t)) part by that rate times t, 7.4e-7 rad a day (tests/test_tle.py);
- polar motion (PEF against ITRF, at most ~0.5", ~15 m at the surface): a station's WGS84 coordinates are
  taken in PEF.
Without an epoch, theta0 is ``earth.theta0_deg`` and the frames are these same ones at an unnamed date.

Array convention: positions are (3,) or (m, 3), states [x y z vx vy vz] are (6,) or (m, 6), one per
row. The time ``t`` may be a scalar or an array (m,) giving one epoch per row.
The ENU frame follows paper 000 eqs. 8-10, except that the station is placed on the WGS84 ellipsoid
(geodetic latitude) instead of the paper's sphere of radius Re + h.
"""

from __future__ import annotations

import datetime as dt_

import numpy as np

from .constants import OMEGA_EARTH, R_EARTH, WGS84_E2, WGS84_F

JD_UNIX_EPOCH = 2440587.5
"""Julian date of 1970-01-01T00:00:00."""
JD_J2000 = 2451545.0
"""Julian date of J2000.0 (2000-01-01T12:00:00)."""
GMST_RATE = 1.002737909350795 * 2.0 * np.pi / 86400.0
"""d(GMST)/dt at J2000 [rad/s]: the linear term of :func:`gmst82` (sidereal days per solar day)."""


def julian_date(epoch: dt_.datetime) -> tuple[float, float]:
    """A timezone-aware datetime (its UTC reading) -> Julian date as (whole part ending in .5, fraction of the
    day), the split that keeps its microseconds (a single double resolves ~40 µs of a Julian date)."""
    utc = epoch.astimezone(dt_.UTC)
    midnight = utc.replace(hour=0, minute=0, second=0, microsecond=0)
    days = (midnight - dt_.datetime(1970, 1, 1, tzinfo=dt_.UTC)).days
    seconds = (utc - midnight) / dt_.timedelta(seconds=1)
    return JD_UNIX_EPOCH + days, seconds / 86400.0


def gmst82(jd_ut1: float, fraction: float = 0.0) -> float:
    """Greenwich mean sidereal time [rad, 0..2 pi) of the UT1 Julian date jd_ut1 + fraction, IAU-82:
    GMST = 67310.54841 s + (876600 h + 8640184.812866 s) T + 0.093104 s T^2 - 6.2e-6 s T^3, T in Julian
    centuries of UT1 from J2000 (Vallado, Fundamentals of Astrodynamics and Applications, eq. 3-47).
    876600 h T is 86400 s per day, whole turns for whole days: only the day's fraction is kept of it, added to
    the fraction itself (a single double's date would resolve only ~80 ns: 6e-12 rad)."""
    whole = np.floor(jd_ut1 - JD_J2000)
    t = ((jd_ut1 - JD_J2000) + fraction) / 36525.0
    seconds = (
        67310.54841
        + 8640184.812866 * t
        + 0.093104 * t * t
        - 6.2e-6 * t**3
        + 86400.0 * (((jd_ut1 - JD_J2000) - whole) + fraction)
    )
    return float(np.mod(seconds / 240.0, 360.0) * np.pi / 180.0)


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
    return np.array([rho * np.cos(lon_rad), rho * np.sin(lon_rad), (n * (1.0 - WGS84_E2) + h_m) * sin_lat])


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
    return np.array([[-so, co, 0.0], [-sl * co, -sl * so, cl], [cl * co, cl * so, sl]])
