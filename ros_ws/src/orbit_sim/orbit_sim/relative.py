"""Relative state of a deputy in the chief's LVLH frame, and the axis conventions of the two papers.

Internal convention (paper 004, section 2): LVLH with x radial (outward, r/|r|), z along the orbit normal
(h/|h|, h = r x v) and y = z x x along-track (the flight direction for a circular orbit). Every relative
state in the bench is stored in this convention; the papers' own axes only appear at the edges, through
``to_convention`` / ``from_convention``:

- ``"radial_along_normal"``: the internal (x radial, y along-track, z normal) axes, paper 004.
- ``"along_radial"``: paper 001, section 1: X along-track (flight direction), Y radial outward and Z
  completing a right-handed frame. Z = X x Y = y_hat x x_hat = -(x_hat x y_hat) = -z_hat: paper 001's Z is
  MINUS the orbit normal. So (X, Y, Z) = (y, x, -z); the map is its own inverse.

The relative velocity is the one seen in the rotating frame: rho_dot = C (v_d - v_c - omega x (r_d - r_c)),
with C the ECI->LVLH rotation and omega the frame's angular velocity. By default omega = (r x v) / r^2
(orbit-normal component only, exact for two-body motion). Under a perturbation with an out-of-plane
component (J2) the frame also turns about x_hat at omega_x = r (a . z_hat) / |h| (~1e-6 rad/s in LEO for J2,
i.e. ~1 mm/s of apparent velocity at 1 km); pass the chief's acceleration ``chief_accel`` to include it,
which makes the relative velocity the exact time derivative of the relative position.

Array convention: a state is (6,) or (m, 6), one per row; the chief may be (6,) (shared) or (m, 6).

``drift_free`` builds a truly bounded truth formation: a relative state chosen with a linear (CW)
bounded-motion condition drifts in the nonlinear two-body + J2 truth (metres to hundreds of metres per
orbit, growing with the formation's size, tests/test_relative.py), because the rectilinear CW condition
ignores curvature and J2 changes the period-matching condition.
"""

from __future__ import annotations

import numpy as np

from .constants import J2_EARTH, MU_EARTH, R_EARTH
from .cowell import propagate
from .gravity import acceleration

CONVENTIONS = ("radial_along_normal", "along_radial")
"""Axis conventions accepted by ``to_convention`` / ``from_convention``."""

_AXES = {
    "radial_along_normal": np.eye(3),
    "along_radial": np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]),
}


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def lvlh_basis(chief_state: np.ndarray) -> np.ndarray:
    """ECI->LVLH rotation C, rows x_hat, y_hat, z_hat in ECI: (3, 3) for (6,), (m, 3, 3) for (m, 6)."""
    s = np.asarray(chief_state, dtype=float)
    x_hat = _unit(s[..., 0:3])
    z_hat = _unit(np.cross(s[..., 0:3], s[..., 3:6]))
    y_hat = np.cross(z_hat, x_hat)
    return np.stack((x_hat, y_hat, z_hat), axis=-2)


def frame_rate(chief_state: np.ndarray, chief_accel: np.ndarray | None = None) -> np.ndarray:
    """Angular velocity omega (ECI components) of the LVLH frame, shape (3,) or (m, 3).

    omega = h / r^2 (h = r x v); with ``chief_accel`` the x_hat component r (a . z_hat) / |h| is added.
    """
    s = np.asarray(chief_state, dtype=float)
    r = s[..., 0:3]
    h = np.cross(r, s[..., 3:6])
    r2 = np.sum(r * r, axis=-1, keepdims=True)
    omega = h / r2
    if chief_accel is not None:
        h_norm = np.linalg.norm(h, axis=-1, keepdims=True)
        a_normal = np.sum(np.asarray(chief_accel, dtype=float) * h, axis=-1, keepdims=True) / h_norm
        omega = omega + r * a_normal / h_norm
    return omega


def _rotate(C: np.ndarray, v: np.ndarray) -> np.ndarray:
    """C v for C (3, 3) or (m, 3, 3) and v (3,) or (m, 3)."""
    return np.einsum("...ij,...j->...i", C, v)


def eci_to_lvlh(chief_state: np.ndarray, deputy_state: np.ndarray, chief_accel: np.ndarray | None = None) -> np.ndarray:
    """Deputy ECI state(s) -> relative [x y z vx vy vz] in the chief's LVLH frame (rotating-frame velocity)."""
    c = np.asarray(chief_state, dtype=float)
    d = np.asarray(deputy_state, dtype=float)
    C = lvlh_basis(c)
    dr = d[..., 0:3] - c[..., 0:3]
    dv = d[..., 3:6] - c[..., 3:6] - np.cross(frame_rate(c, chief_accel), dr)
    return np.concatenate((_rotate(C, dr), _rotate(C, dv)), axis=-1)


def lvlh_to_eci(chief_state: np.ndarray, rel: np.ndarray, chief_accel: np.ndarray | None = None) -> np.ndarray:
    """Exact inverse of ``eci_to_lvlh``: relative LVLH state(s) -> deputy ECI state(s)."""
    c = np.asarray(chief_state, dtype=float)
    rel = np.asarray(rel, dtype=float)
    Ct = np.swapaxes(lvlh_basis(c), -1, -2)
    dr = _rotate(Ct, rel[..., 0:3])
    dv = _rotate(Ct, rel[..., 3:6]) + np.cross(frame_rate(c, chief_accel), dr)
    return np.concatenate((c[..., 0:3] + dr, c[..., 3:6] + dv), axis=-1)


def convention_matrix(convention: str) -> np.ndarray:
    """3x3 matrix M mapping internal axes to ``convention`` axes (u_conv = M u_internal); M is orthogonal."""
    if convention not in _AXES:
        raise ValueError(f"unknown LVLH convention {convention!r}; expected one of {CONVENTIONS}")
    return _AXES[convention]


def _apply_blocks(M: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Apply M to every consecutive 3-block (position, velocity, bias, ...) of v (..., 3k)."""
    v = np.asarray(v, dtype=float)
    if v.shape[-1] % 3:
        raise ValueError(f"relative vector length {v.shape[-1]} is not a multiple of 3")
    blocks = v.reshape(v.shape[:-1] + (v.shape[-1] // 3, 3))
    return np.einsum("ij,...kj->...ki", M, blocks).reshape(v.shape)


def to_convention(rel: np.ndarray, convention: str) -> np.ndarray:
    """Internal relative vector(s) (..., 3k) -> the same vector(s) in ``convention`` axes.

    Works on 3- (position), 6- (position, velocity) and 9-vectors (position, velocity, bias).
    """
    return _apply_blocks(convention_matrix(convention), rel)


def from_convention(rel: np.ndarray, convention: str) -> np.ndarray:
    """Inverse of ``to_convention``: vector(s) in ``convention`` axes -> internal axes."""
    return _apply_blocks(convention_matrix(convention).T, rel)


def _mean_along_track_drift(
    chief_state: np.ndarray, rel: np.ndarray, period: float, samples: int, mu: float, j2: float, re: float
) -> float:
    """Truth (two-body + J2) along-track drift [m/orbit]: mean y over orbit 2 minus mean y over orbit 1."""
    t = np.linspace(0.0, 2.0 * period, 2 * samples + 1)
    chief = propagate(chief_state, t, mu, j2, re)
    accel = acceleration(chief[:, 0:3], mu, j2, re)
    deputy = propagate(lvlh_to_eci(chief_state, rel, accel[0]), t, mu, j2, re)
    y = eci_to_lvlh(chief, deputy, accel)[:, 1]
    return float(y[samples : 2 * samples].mean() - y[:samples].mean())


def drift_free(
    chief_state: np.ndarray,
    rel: np.ndarray,
    mu: float = MU_EARTH,
    j2: float = J2_EARTH,
    re: float = R_EARTH,
    samples_per_orbit: int = 100,
) -> np.ndarray:
    """Copy of ``rel`` (6,) with its along-track velocity adjusted so that the deputy has no mean
    along-track drift relative to the chief in the nonlinear two-body + J2 truth.

    The relative state is taken with the exact frame rate (chief acceleration included). The drift over one
    orbit (orbit-mean y of the second orbit minus that of the first) is linear in vy to first order, so
    one secant step (trial offset 1 mm/s) from two truth propagations nulls it (to < 1 % of the drift).
    """
    rel = np.array(rel, dtype=float)
    c = np.asarray(chief_state, dtype=float)
    energy = 0.5 * float(c[3:6] @ c[3:6]) - mu / float(np.linalg.norm(c[0:3]))
    period = 2.0 * np.pi * np.sqrt((-mu / (2.0 * energy)) ** 3 / mu)
    d0 = _mean_along_track_drift(c, rel, period, samples_per_orbit, mu, j2, re)
    step = 1e-3
    trial = rel.copy()
    trial[4] += step
    d1 = _mean_along_track_drift(c, trial, period, samples_per_orbit, mu, j2, re)
    rel[4] -= d0 * step / (d1 - d0)
    return rel
