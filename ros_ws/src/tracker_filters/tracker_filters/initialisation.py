"""Initial state "from the first radar scan" (paper 000, section 6; SCENARIOS.md section 1).

Position: the inverse polar conversion of the first (range, azimuth, elevation), with covariance
J R J^T, J = d position / d (range, azimuth, elevation) at the measurement. The first-order mapping is
adequate: its neglected second-order term (the curvature of the range shell, ~range sigma_angle^2 / 2,
about 0.3 km at 2000 km with 1 deg noise) is 1 % of the cross-range standard deviation it sits in
(range sigma_angle, about 34 km).

Velocity: a single scan carries no velocity information, so it comes from a prior: a mean (default zero)
and a standard deviation per axis, or a full 3x3 covariance. ``circular_orbit_velocity_prior`` gives the
prior a LEO object implies at the measured position: speed sqrt(mu / |r|), direction unknown within the
plane normal to r. See tests/test_leo_consistency.py and the leo_radar scenario for the measured choice.
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


def initial_state_from_scan(z: np.ndarray, R: np.ndarray, model, t: float,
                            velocity_sigma: float | np.ndarray,
                            velocity_mean: np.ndarray | None = None,
                            method: str = "unscented") -> tuple[np.ndarray, np.ndarray]:
    """(x0 (6,), P0 (6, 6)) in ECI at time t from one radar measurement z with noise covariance R.

    ``model`` is a radar measurement model offering ``position_from_measurement(z, t)`` and
    ``position_jacobian(z, t)`` (radar_sensor.radar.GroundRadarModel). Only the first three components of
    z (range, azimuth, elevation) and the matching 3x3 block of R are used.
    """
    z3 = np.asarray(z, dtype=float)[0:3]
    R3 = np.asarray(R, dtype=float)[0:3, 0:3]
    if method == "jacobian":
        r0 = model.position_from_measurement(z3, t)
        J = model.position_jacobian(z3, t)
        P_pos = J @ R3 @ J.T
    elif method == "unscented":
        points = ScaledSigmaPoints(3, alpha=1.0, beta=2.0, kappa=0.0)
        positions = np.array([model.position_from_measurement(zi, t) for zi in points.generate(z3, R3)])
        r0 = points.mean(positions)
        P_pos = points.covariance(positions - r0)
    else:
        raise ValueError(f"method must be 'unscented' or 'jacobian', got {method!r}")
    v0 = np.zeros(3) if velocity_mean is None else np.asarray(velocity_mean, dtype=float)
    x0 = np.concatenate((r0, v0))
    P0 = np.zeros((6, 6))
    P0[0:3, 0:3] = P_pos
    P0[3:6, 3:6] = _velocity_covariance(velocity_sigma)
    return x0, P0


def circular_orbit_velocity_prior(r_eci: np.ndarray, radial_sigma: float = 100.0,
                                  mu: float = MU_EARTH) -> tuple[np.ndarray, np.ndarray]:
    """Zero-mean Gaussian moment match of "circular-orbit speed, unknown direction normal to r".

    A velocity of magnitude v_c = sqrt(mu / |r|) spread uniformly over the circle normal to r has mean 0
    and covariance (v_c^2 / 2)(I - u u^T), u = r / |r|; ``radial_sigma`` [m/s] adds the small radial
    velocity of a near-circular orbit. Returns (mean (3,), covariance (3, 3)).
    """
    r = np.asarray(r_eci, dtype=float)
    u = r / np.linalg.norm(r)
    vc2 = mu / np.linalg.norm(r)
    uu = np.outer(u, u)
    return np.zeros(3), 0.5 * vc2 * (np.eye(3) - uu) + radial_sigma ** 2 * uu
