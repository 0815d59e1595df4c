"""Ground radar on the rotating Earth: range, azimuth, elevation (and optionally range rate) of an ECI state.

Paper 000, eqs. 8-16. The station sits at WGS84 geodetic (lat, lon, h) (``frames.geodetic_to_ecef``; the
paper uses a sphere of radius Re + h, eq. 8). A state's ECI position is rotated to ECEF with the Earth
rotation angle theta(t) = theta0 + OMEGA_EARTH t, then to the station's East-North-Up frame (eqs. 9-10):

    u = M (R3(theta) r_eci - s) = T(t) r_eci - M s,        T(t) = M R3(theta(t))

and converted to polar form (eqs. 11-13):

    range = |u|,  azimuth = atan2(u_E, u_N) in [0, 2 pi),  elevation = atan2(u_U, hypot(u_E, u_N)).

Azimuth convention: the paper writes theta = atan(y/x) in ENU (counter-clockwise from East, and quadrant-
ambiguous). Radars report azimuth clockwise from North, so this model uses atan2(East, North), wrapped to
[0, 2 pi). Consequently the azimuth row of the Jacobian differs from the paper's eq. 16 (whose H22 also has
a sign error: d atan(y/x)/dy = +x/(x^2 + y^2)).

Range rate (optional 4th component) is the rate of |u| seen from the Earth-fixed station:
    w = T (v_eci - omega x r_eci),   range_rate = u . w / |u|.

Hessians (``hessian``, and with h and the Jacobian in one pass ``derivatives``, for second-order filters,
e.g. ekf.SecondOrderEKF). Since (u, w) is an affine map
J = [[T, 0], [-T [omega x], T]] of the state, each component's Hessian is J^T (d^2 h / d(u, w)^2) J, with,
for rho = |u|, n_u = u / rho, q = u_E^2 + u_N^2 and g = d range_rate / d u = (w - range_rate n_u) / rho:
    range       (I - n_u n_u^T) / rho
    azimuth     [[-2 u_E u_N, u_E^2 - u_N^2], [u_E^2 - u_N^2, 2 u_E u_N]] / q^2 in the (E, N) block
    elevation   see ``_elevation_hessian``
    range_rate  uu: -(n_u g^T + g n_u^T) / rho - range_rate (I - n_u n_u^T) / rho^2,  uw: (I - n_u n_u^T) / rho
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from bench_models.models import angle_components
from orbit_sim.angles import wrapped_residual
from orbit_sim.constants import OMEGA_EARTH
from orbit_sim.frames import earth_rotation_angle, enu_rotation, geodetic_to_ecef

_TWO_PI = 2.0 * np.pi
_OMEGA_SKEW = np.array([[0.0, -OMEGA_EARTH, 0.0], [OMEGA_EARTH, 0.0, 0.0], [0.0, 0.0, 0.0]])
"""[omega x] for the Earth rotation vector omega = OMEGA_EARTH e_z."""


class GroundRadarModel:
    """MeasurementModel of a ground radar at WGS84 (lat, lon, h) for ECI states [x y z vx vy vz, ...].

    Extra state components beyond the first six are ignored (their Jacobian columns are zero).
    """

    def __init__(
        self, lat_rad: float, lon_rad: float, h_m: float, theta0: float = 0.0, with_range_rate: bool = False
    ) -> None:
        self.lat_rad = float(lat_rad)
        self.lon_rad = float(lon_rad)
        self.h_m = float(h_m)
        self.theta0 = float(theta0)
        self.with_range_rate = bool(with_range_rate)
        self.station_ecef = geodetic_to_ecef(self.lat_rad, self.lon_rad, self.h_m)
        self._M = enu_rotation(self.lat_rad, self.lon_rad)
        self._station_enu = self._M @ self.station_ecef
        self._T_cache: tuple[float, np.ndarray] = (float("nan"), np.eye(3))
        base = ("range", "azimuth", "elevation")
        self.labels: Sequence[str] = (base + ("range_rate",)) if self.with_range_rate else base
        self.angle_indices: Sequence[int] = angle_components(self.labels)

    def eci_to_enu_rotation(self, t: float) -> np.ndarray:
        """T(t) = M R3(theta(t)): ECI vector components -> station ENU components, shape (3, 3).

        The last T is cached: a filter step evaluates h and its Jacobian at the same time t.
        """
        if t != self._T_cache[0]:
            theta = float(earth_rotation_angle(t, self.theta0))
            c, s = math.cos(theta), math.sin(theta)
            T = self._M @ np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
            T.flags.writeable = False
            self._T_cache = (t, T)
        return self._T_cache[1]

    def enu(self, x: np.ndarray, t: float) -> np.ndarray:
        """Station-to-target vector in ENU (paper eq. 10) for a state (n,) -> (3,) or batch (m, n) -> (m, 3)."""
        x = np.asarray(x, dtype=float)
        return x[..., 0:3] @ self.eci_to_enu_rotation(t).T - self._station_enu

    def h(self, x: np.ndarray, t: float) -> np.ndarray:
        """[range, azimuth, elevation(, range_rate)] (paper eqs. 11-14) for (n,) -> (d,) or (m, n) -> (m, d).

        A single state is converted in Python floats (numpy's per-call overhead on 3-vectors would
        dominate the EKF's step time); a batch is vectorised over rows (``_polar_rows``).
        """
        x = np.asarray(x, dtype=float)
        T = self.eci_to_enu_rotation(t)
        if x.ndim == 1:
            return np.array(_values(*self._relative(x, T)))
        u = x[..., 0:3] @ T.T - self._station_enu
        w = (x[..., 3:6] - x[..., 0:3] @ _OMEGA_SKEW.T) @ T.T if self.with_range_rate else None
        return _polar_rows(u, w)

    def elevation(self, x: np.ndarray, t: float) -> np.ndarray | float:
        """Elevation [rad] of a state (n,) -> float or batch (m, n) -> (m,), for the visibility mask."""
        u = self.enu(x, t)
        el = np.arctan2(u[..., 2], np.hypot(u[..., 0], u[..., 1]))
        return float(el) if np.ndim(el) == 0 else el

    def jacobian(self, x: np.ndarray, t: float) -> np.ndarray:
        """Analytic d h / d x at a single state x (n,), shape (d, n) (paper eqs. 15-16, radar azimuth).

        Singular at the zenith (horizontal distance 0), where azimuth is undefined.
        """
        x = np.asarray(x, dtype=float)
        T = self.eci_to_enu_rotation(t)
        return _jacobian(T, *self._relative(x, T), x.shape[0])

    def hessian(self, x: np.ndarray, t: float) -> np.ndarray:
        """Analytic second derivatives d^2 h_i / d x^2 at a single state x (n,), shape (d, n, n).

        Only the position block is non-zero for range, azimuth and elevation; the range rate also couples
        position and velocity (module docstring). Singular at the zenith, like the Jacobian.
        """
        x = np.asarray(x, dtype=float)
        T = self.eci_to_enu_rotation(t)
        block = _hessians(T, *self._relative(x, T))
        m = block.shape[-1]
        Hs = np.zeros((len(self.labels), x.shape[0], x.shape[0]))
        Hs[:, 0:m, 0:m] = block
        return Hs

    def derivatives(self, x: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``h`` (d,), ``jacobian`` (d, n) and the Hessians' leading block (d, m, m) at one state x (n,).

        The Hessians are zero outside the first m state components: m = 3 (position) for range, azimuth
        and elevation, m = 6 with the range rate. One shared pass with the same arithmetic as the three
        methods (equal results), cheaper than the three calls (range, azimuth, elevation; T cached).
        ekf.SecondOrderEKF calls it every step.
        """
        x = np.asarray(x, dtype=float)
        T = self.eci_to_enu_rotation(t)
        u, w = self._relative(x, T)
        return np.array(_values(u, w)), _jacobian(T, u, w, x.shape[0]), _hessians(T, u, w)

    def _relative(self, x: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """u = T r - M s (3,) of one state x (n,) and, with range rate, w = T (v - omega x r) (3,), else None.

        ``ndarray.dot`` rather than ``@``: the same BLAS call without the matmul ufunc's dispatch (likewise in
        the helpers below)."""
        u = T.dot(x[0:3]) - self._station_enu
        if not self.with_range_rate:
            return u, None
        return u, T.dot(x[3:6] - _OMEGA_SKEW.dot(x[0:3]))

    def residual(self, z: np.ndarray, z_pred: np.ndarray) -> np.ndarray:
        """z - z_pred with azimuth and elevation wrapped to (-pi, pi]; broadcasts over batches."""
        return wrapped_residual(z, z_pred, self.angle_indices)

    def position_from_measurement(self, z: np.ndarray, t: float) -> np.ndarray:
        """ECI position (3,) of the target seen at [range, azimuth, elevation, ...] z at time t.

        Inverse of the polar conversion (eqs. 11-13) and of the ENU/ECEF rotations (eqs. 9-10).
        """
        rng, az, el = (float(v) for v in np.asarray(z, dtype=float)[0:3])
        u = rng * np.array([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)])
        return self.eci_to_enu_rotation(t).T @ (u + self._station_enu)

    def position_jacobian(self, z: np.ndarray, t: float) -> np.ndarray:
        """d position_from_measurement / d [range, azimuth, elevation], shape (3, 3)."""
        rng, az, el = (float(v) for v in np.asarray(z, dtype=float)[0:3])
        ca, sa, ce, se = np.cos(az), np.sin(az), np.cos(el), np.sin(el)
        d_u = np.array(
            [[ce * sa, rng * ce * ca, -rng * se * sa], [ce * ca, -rng * ce * sa, -rng * se * ca], [se, 0.0, rng * ce]]
        )
        return self.eci_to_enu_rotation(t).T @ d_u

    # Scans at different times (batch re-solves, tracker_filters/relinearisation.py): one state per time,
    # vectorised over scans with one ECI -> ENU rotation T(t_j) each.

    def h_series(self, x: np.ndarray, times: np.ndarray) -> np.ndarray:
        """``h`` of state x[j] (m, n) at time times[j] (m,) for every j, shape (m, d)."""
        return _polar_rows(*self._enu_series(np.asarray(x, dtype=float), self._enu_rotation_series(times)))

    def jacobian_series(self, x: np.ndarray, times: np.ndarray) -> np.ndarray:
        """``jacobian`` at state x[j] (m, n) and time times[j] (m,) for every j, shape (m, d, n)."""
        x = np.asarray(x, dtype=float)
        T = self._enu_rotation_series(times)
        u, w = self._enu_series(x, T)
        e, n, up = u[:, 0], u[:, 1], u[:, 2]
        horiz2 = e * e + n * n
        horiz = np.sqrt(horiz2)
        rng2 = horiz2 + up * up
        rng = np.sqrt(rng2)
        c = up / (rng2 * horiz)
        d_polar = np.empty((x.shape[0], 3, 3))
        d_polar[:, 0] = u / rng[:, None]
        d_polar[:, 1, 0], d_polar[:, 1, 1], d_polar[:, 1, 2] = n / horiz2, -e / horiz2, 0.0
        d_polar[:, 2, 0], d_polar[:, 2, 1], d_polar[:, 2, 2] = -e * c, -n * c, horiz / rng2
        H = np.zeros((x.shape[0], len(self.labels), x.shape[1]))
        H[:, 0:3, 0:3] = d_polar @ T
        if self.with_range_rate:
            d_w = u / rng[:, None]
            rdot = np.sum(d_w * w, axis=-1)
            d_u = (w - rdot[:, None] * d_w) / rng[:, None]
            d_w_T = np.einsum("mi,mij->mj", d_w, T)
            H[:, 3, 0:3] = np.einsum("mi,mij->mj", d_u, T) - d_w_T @ _OMEGA_SKEW
            H[:, 3, 3:6] = d_w_T
        return H

    def _enu_rotation_series(self, times: np.ndarray) -> np.ndarray:
        """T(t_j) = M R3(theta(t_j)) for every time (m,), shape (m, 3, 3)."""
        theta = earth_rotation_angle(np.asarray(times, dtype=float), self.theta0)
        c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
        T = np.empty((theta.shape[0], 3, 3))
        T[:, :, 0] = c * self._M[:, 0] - s * self._M[:, 1]
        T[:, :, 1] = s * self._M[:, 0] + c * self._M[:, 1]
        T[:, :, 2] = self._M[:, 2]
        return T

    def _enu_series(self, x: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """u = T r - M s (m, 3) and, with range rate, w = T (v - omega x r) (m, 3) (else None)."""
        u = np.einsum("mij,mj->mi", T, x[:, 0:3]) - self._station_enu
        if not self.with_range_rate:
            return u, None
        return u, np.einsum("mij,mj->mi", T, x[:, 3:6] - x[:, 0:3] @ _OMEGA_SKEW.T)


def _shell(e: float, n: float, up: float, rng: float, rng2: float) -> list[float]:
    """d^2 range / d u^2 = (I - u u^T / rng^2) / rng (3x3, ENU, row-major flat): the range shell's curvature."""
    ir, ir3 = 1.0 / rng, 1.0 / (rng * rng2)
    en, eu, nu = -e * n * ir3, -e * up * ir3, -n * up * ir3
    return [ir - e * e * ir3, en, eu, en, ir - n * n * ir3, nu, eu, nu, ir - up * up * ir3]


def _elevation_hessian(e: float, n: float, up: float, q: float, rng2: float) -> list[float]:
    """d^2 elevation / d u^2 (3x3, ENU, row-major flat) for el = atan2(up, h), h = sqrt(q), q = e^2 + n^2 and
    rng2 = q + up^2.

    With c = up / (rng2 h) (so d el / d e = -e c) and k = up (2 / (rng2^2 h) + 1 / (rng2 h^3)):
    d2/de2 = -c + k e^2, d2/dn2 = -c + k n^2, d2/de dn = k e n, d2/de dup = -e (q - up^2) / (rng2^2 h),
    likewise for n, and d2/dup2 = -2 up h / rng2^2.
    """
    h = math.sqrt(q)
    c = up / (rng2 * h)
    k = up * (2.0 / (rng2 * rng2 * h) + 1.0 / (rng2 * q * h))
    m = (q - up * up) / (rng2 * rng2 * h)
    return [
        k * e * e - c,
        k * e * n,
        -e * m,
        k * e * n,
        k * n * n - c,
        -n * m,
        -e * m,
        -n * m,
        -2.0 * up * h / (rng2 * rng2),
    ]


def _values(u: np.ndarray, w: np.ndarray | None) -> list[float]:
    """[range, azimuth, elevation(, range_rate)] of one state from its u and w (``GroundRadarModel.h``).

    In Python floats: numpy's per-call overhead on 3-vectors would dominate the EKF's step time."""
    e, n, up = u.tolist()
    horiz = math.hypot(e, n)
    rng = math.hypot(horiz, up)
    z = [rng, math.atan2(e, n) % _TWO_PI, math.atan2(up, horiz)]
    if w is not None:
        z.append(float(u.dot(w)) / rng)
    return z


def _polar_rows(u: np.ndarray, w: np.ndarray | None) -> np.ndarray:
    """[range, azimuth, elevation(, range_rate)] (m, d) of rows u (m, 3) and w (m, 3) or None, each component
    written straight into its column (no np.stack on the UKF's 13 sigma points)."""
    e, n, up = u[..., 0], u[..., 1], u[..., 2]
    z = np.empty(u.shape[:-1] + (3 if w is None else 4,))
    horiz = np.hypot(e, n)
    rng = np.hypot(horiz, up, out=z[..., 0])
    np.mod(np.arctan2(e, n), _TWO_PI, out=z[..., 1])
    np.arctan2(up, horiz, out=z[..., 2])
    if w is not None:
        np.divide(np.sum(u * w, axis=-1), rng, out=z[..., 3])
    return z


def _jacobian(T: np.ndarray, u: np.ndarray, w: np.ndarray | None, size: int) -> np.ndarray:
    """d h / d x (d, size) of one state from T, u and w (``GroundRadarModel.jacobian``)."""
    e, n, up = u.tolist()
    horiz2 = e * e + n * n
    horiz = math.sqrt(horiz2)
    rng2 = horiz2 + up * up
    rng = math.sqrt(rng2)
    c = up / (rng2 * horiz)
    d_polar = np.array(
        [e / rng, n / rng, up / rng, n / horiz2, -e / horiz2, 0.0, -e * c, -n * c, horiz / rng2]
    ).reshape(3, 3)  # a flat list converts faster than nested ones
    H = np.zeros((3 if w is None else 4, size))
    H[0:3, 0:3] = d_polar.dot(T)
    if w is not None:
        rdot = float(u.dot(w)) / rng
        d_u = (w - rdot * u / rng) / rng
        d_w = u / rng
        H[3, 0:3] = d_u.dot(T) - d_w.dot(T).dot(_OMEGA_SKEW)
        H[3, 3:6] = d_w.dot(T)
    return H


def _hessians(T: np.ndarray, u: np.ndarray, w: np.ndarray | None) -> np.ndarray:
    """d^2 h_i / d x^2 of one state over the first 3 state components (3, 3, 3), or 6 with the range rate
    (4, 6, 6) (``GroundRadarModel.hessian``). The ENU Hessians are formed in Python floats, as one flat list
    (numpy converts it faster than nested ones)."""
    e, n, up = u.tolist()
    q = e * e + n * n
    rng2 = q + up * up
    rng = math.sqrt(rng2)
    a = 1.0 / (q * q)
    en2, diff = 2.0 * e * n * a, (e * e - n * n) * a
    azimuth = [-en2, diff, 0.0, diff, en2, 0.0, 0.0, 0.0, 0.0]
    polar = np.array(_shell(e, n, up, rng, rng2) + azimuth + _elevation_hessian(e, n, up, q, rng2))
    polar = polar.reshape(3, 3, 3)
    position = T.T @ polar @ T
    if w is None:
        return position
    Hs = np.zeros((4, 6, 6))
    Hs[0:3, 0:3, 0:3] = position
    Hs[3] = _range_rate_hessian(T, u, w, rng, polar[0])
    return Hs


def _range_rate_hessian(T: np.ndarray, u: np.ndarray, w: np.ndarray, rng: float, shell: np.ndarray) -> np.ndarray:
    """d^2 range_rate / d [r, v]^2 (6, 6) = J^T (d^2 range_rate / d (u, w)^2) J (module docstring)."""
    nu = u / rng
    rdot = float(nu @ w)
    g = (w - rdot * nu) / rng
    H_uw = np.zeros((6, 6))
    H_uw[0:3, 0:3] = -(np.outer(nu, g) + np.outer(g, nu)) / rng - rdot * shell / rng
    H_uw[0:3, 3:6] = shell
    H_uw[3:6, 0:3] = shell
    J = np.zeros((6, 6))
    J[0:3, 0:3] = T
    J[3:6, 0:3] = -T @ _OMEGA_SKEW
    J[3:6, 3:6] = T
    return J.T @ H_uw @ J
