"""Initial state "from the first radar scan" (paper 000, section 6: the leo_radar study).

Position: the inverse polar conversion of the first (range, azimuth, elevation). Default: its mean and
covariance by the unscented transform of the measurement noise (3-D scaled sigma points, alpha = 1,
beta = 2, kappa = 0). With 1 deg angle noise the scan's cross-range spread is ~25 km at 1500 km range,
and over that spread the range shell curves by ~range sigma_angle^2 ~ 0.4 km, more than ten times sigma_r.
The first-order map (``method="jacobian"``, covariance J R J^T) gives the range direction only sigma_r and
is grossly overconfident, the unscented transform is not (tests/test_radar_model.py checks both NEES).

Velocity: one scan carries no velocity information, so it comes from a prior: a mean (default zero) and
a standard deviation per axis, or a full 3x3 covariance (e.g. zero mean with 8 km/s per axis: a low orbit's
speed in any direction). ``circular_orbit_velocity_prior`` (circular-orbit speed, unknown direction normal to
r) and the isotropic moment match (v_c^2 / 3 per axis) are the alternatives; none of them changes the start-up
inconsistency, which comes from the measurement geometry, not the velocity prior (relinearisation.py).
"""

from __future__ import annotations

import numpy as np

from orbit_sim.constants import MU_EARTH
from tracker_filters.sigma_points import ScaledSigmaPoints


def _velocity_covariance(velocity_sigma: float | np.ndarray) -> np.ndarray:
    """3x3 covariance from a scalar sigma, per-axis sigmas (3,), or a 3x3 covariance."""
    s = np.asarray(velocity_sigma, dtype=float)
    if s.shape == (3, 3):
        return s
    if s.shape in ((), (3,)) and np.all(s > 0.0) and np.all(np.isfinite(s)):
        return np.diag(np.broadcast_to(s, (3,)) ** 2)
    raise ValueError(f"velocity_sigma must be a positive scalar, (3,) sigmas or a 3x3 covariance, got {s!r}")


def initial_state_from_scan(
    z: np.ndarray,
    R: np.ndarray,
    model,
    t: float,
    velocity_sigma: float | np.ndarray,
    velocity_mean: np.ndarray | None = None,
    method: str = "unscented",
) -> tuple[np.ndarray, np.ndarray]:
    """(x0 (6,), P0 (6, 6)) in ECI at time t from one radar measurement z with noise covariance R.

    ``model`` is a radar measurement model offering ``position_from_measurement(z, t)`` and
    ``position_jacobian(z, t)`` (bench_models.radar.GroundRadarModel). Only the first three components of
    z (range, azimuth, elevation) and the matching 3x3 block of R are used.
    """
    r0, P_pos = scan_position(z, R, model, t, method)
    v0 = np.zeros(3) if velocity_mean is None else np.asarray(velocity_mean, dtype=float)
    x0 = np.concatenate((r0, v0))
    P0 = np.zeros((6, 6))
    P0[0:3, 0:3] = P_pos
    P0[3:6, 3:6] = _velocity_covariance(velocity_sigma)
    return x0, P0


def scan_position(
    z: np.ndarray, R: np.ndarray, model, t: float, method: str = "unscented"
) -> tuple[np.ndarray, np.ndarray]:
    """ECI position (3,) and its covariance (3, 3) implied by one scan z (range, azimuth, elevation, ...)."""
    z3 = np.asarray(z, dtype=float)[0:3]
    R3 = np.asarray(R, dtype=float)[0:3, 0:3]
    if method == "jacobian":
        J = model.position_jacobian(z3, t)
        return model.position_from_measurement(z3, t), J @ R3 @ J.T
    if method == "unscented":
        points = ScaledSigmaPoints(3, alpha=1.0, beta=2.0, kappa=0.0)
        positions = np.array([model.position_from_measurement(zi, t) for zi in points.generate(z3, R3)])
        r0 = points.mean(positions)
        return r0, points.covariance(positions - r0)
    raise ValueError(f"method must be 'unscented' or 'jacobian', got {method!r}")


def circular_orbit_velocity_prior(
    r_eci: np.ndarray, radial_sigma: float = 100.0, mu: float = MU_EARTH
) -> tuple[np.ndarray, np.ndarray]:
    """Zero-mean Gaussian moment match of "circular-orbit speed, unknown direction normal to r".

    A velocity of magnitude v_c = sqrt(mu / |r|) spread uniformly over the circle normal to r has mean 0
    and covariance (v_c^2 / 2)(I - u u^T), u = r / |r|; ``radial_sigma`` [m/s] adds the small radial
    velocity of a near-circular orbit. Returns (mean (3,), covariance (3, 3)).
    """
    r = np.asarray(r_eci, dtype=float)
    u = r / np.linalg.norm(r)
    vc2 = mu / np.linalg.norm(r)
    uu = np.outer(u, u)
    return np.zeros(3), 0.5 * vc2 * (np.eye(3) - uu) + radial_sigma**2 * uu
