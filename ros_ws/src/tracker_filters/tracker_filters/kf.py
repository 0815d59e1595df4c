"""Linear Kalman filter (Joseph form) and the Gaussian update algebra the EKF and UKF share.

The small dense factorisations call LAPACK (dpotrf/dpotrs) directly: on 3x3 .. 6x6 matrices numpy's and
scipy's wrappers cost 5-10 us per call against ~1 us for the routine itself, which matters for the
100 us (EKF) / 300 us (UKF) per-step budgets (measured with scripts/bench_filters.py).
"""
from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

from tracker_filters.filter_base import Filter
from tracker_filters.models import MeasurementModel


def cholesky_lower(A: np.ndarray) -> np.ndarray:
    """Lower Cholesky factor L (L L^T = A); raises LinAlgError when A is not positive definite."""
    L, info = lapack.dpotrf(A, lower=1, clean=1)
    if info != 0:
        raise np.linalg.LinAlgError(f"Cholesky factorisation failed (LAPACK info={info})")
    return L


def cholesky_solve(L: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Solve (L L^T) X = B given the lower Cholesky factor L."""
    X, info = lapack.dpotrs(L, B, lower=1)
    if info != 0:
        raise np.linalg.LinAlgError(f"Cholesky solve failed (LAPACK info={info})")
    return X


def gain_and_nis(C: np.ndarray, S: np.ndarray, nu: np.ndarray) -> tuple[np.ndarray, float]:
    """Kalman gain K = C S^-1 and NIS nu^T S^-1 nu, with C the state-measurement cross-covariance (n, d).

    S is factorised by Cholesky, so a non-positive-definite innovation covariance raises LinAlgError.
    """
    n = C.shape[0]
    B = np.empty((nu.shape[0], n + 1))
    B[:, 0:n] = C.T
    B[:, n] = nu
    sol = cholesky_solve(cholesky_lower(S), B)
    return sol[:, 0:n].T, float(nu @ sol[:, n])


def joseph_update(x: np.ndarray, P: np.ndarray, nu: np.ndarray, H: np.ndarray,
                  R: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Kalman measurement update with innovation nu and measurement matrix H (paper eq. 20).

    The covariance uses the Joseph form P = (I - K H) P (I - K H)^T + K R K^T, which stays symmetric
    positive semi-definite for any gain; the paper's P - K S K^T is algebraically equal at the optimal gain.
    Returns (x, P, NIS).
    """
    PHt = P @ H.T
    S = H @ PHt + R
    K, nis = gain_and_nis(PHt, S, nu)
    IKH = -K @ H
    IKH.flat[::x.shape[0] + 1] += 1.0
    return x + K @ nu, IKH @ P @ IKH.T + K @ R @ K.T, nis


class KalmanFilter(Filter):
    """Linear Kalman filter: x <- F x, P <- F P F^T + Q; Joseph-form update.

    Meant for linear models (``linear_models``): F = dynamics.transition_matrix, H = model.jacobian and
    the innovation z - h(x) (= z - H x for a linear model, angle-wrapped by the model's residual).
    """

    name = "kf"

    def _predict(self, dt: float) -> None:
        F = self.dynamics.transition_matrix(self.x, dt)
        Q = self.dynamics.process_noise(self.x, dt)
        self.x = F @ self.x
        self.P = F @ self.P @ F.T + Q

    def _update(self, z: np.ndarray, R: np.ndarray, model: MeasurementModel) -> float:
        H = model.jacobian(self.x, self.t)
        nu = model.residual(z, model.h(self.x, self.t))
        self.x, self.P, nis = joseph_update(self.x, self.P, nu, H, R)
        return nis
