"""Linear models: constant-velocity dynamics and a position measurement (KF, UKF = KF and NEES tests)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bench_engine.labels import POSITION, VELOCITY
from orbit_sim.angles import wrapped_residual


def white_acceleration_q(q: float, dt: float, ndim: int) -> np.ndarray:
    """Discrete Q of continuous white acceleration (PSD q per axis) for states [pos (ndim), vel (ndim)]."""
    a = abs(dt)
    eye = np.eye(ndim)
    Q = np.empty((2 * ndim, 2 * ndim))
    Q[:ndim, :ndim] = eye * (q * a**3 / 3.0)
    Q[:ndim, ndim:] = Q[ndim:, :ndim] = eye * (q * a * a / 2.0)
    Q[ndim:, ndim:] = eye * (q * a)
    return Q


def _check_ndim(ndim: int) -> int:
    if ndim not in (1, 2, 3):
        raise ValueError(f"ndim must be 1, 2 or 3, got {ndim}")
    return ndim


class ConstantVelocity:
    """DynamicsModel: state [positions (ndim), velocities (ndim)], white acceleration of PSD sigma_accel^2.

    x(t + dt) = F x(t), F = [[I, dt I], [0, I]]; Q per axis sigma_accel^2 [[dt^3/3, dt^2/2], [dt^2/2, dt]].
    """

    def __init__(self, sigma_accel: float, ndim: int = 3, frame: str = "eci") -> None:
        if not sigma_accel >= 0.0:
            raise ValueError(f"sigma_accel must be >= 0, got {sigma_accel}")
        self.ndim = _check_ndim(ndim)
        self.sigma_accel = float(sigma_accel)
        self.frame = frame
        self.labels: Sequence[str] = POSITION[:ndim] + VELOCITY[:ndim]

    def transition_matrix(self, x: np.ndarray, dt: float) -> np.ndarray:
        """F(dt), shape (2 ndim, 2 ndim); independent of x."""
        F = np.eye(2 * self.ndim)
        F[0 : self.ndim, self.ndim :] = dt * np.eye(self.ndim)
        return F

    def propagate(self, x: np.ndarray, dt: float) -> np.ndarray:
        """F x for one state (n,) or a batch (m, n)."""
        return np.asarray(x, dtype=float) @ self.transition_matrix(x, dt).T

    def process_noise(self, x: np.ndarray, dt: float) -> np.ndarray:
        """Discrete white-acceleration Q(dt)."""
        return white_acceleration_q(self.sigma_accel**2, dt, self.ndim)


class PositionMeasurement:
    """MeasurementModel z = H x + v with H = [I 0]: the first ``ndim`` state components (positions)."""

    angle_indices: Sequence[int] = ()

    def __init__(self, ndim: int = 3) -> None:
        self.ndim = _check_ndim(ndim)
        self.labels: Sequence[str] = POSITION[:ndim]

    def h(self, x: np.ndarray, t: float) -> np.ndarray:
        """Positions of one state (n,) -> (ndim,) or a batch (m, n) -> (m, ndim)."""
        return np.array(np.asarray(x, dtype=float)[..., 0 : self.ndim])

    def jacobian(self, x: np.ndarray, t: float) -> np.ndarray:
        """H = [I 0], shape (ndim, n) for a state x of length n."""
        return np.eye(self.ndim, np.shape(x)[-1])

    def residual(self, z: np.ndarray, z_pred: np.ndarray) -> np.ndarray:
        """Plain difference z - z_pred (no angles)."""
        return wrapped_residual(z, z_pred, self.angle_indices)
