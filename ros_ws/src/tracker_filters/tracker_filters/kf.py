"""Linear Kalman filter (Joseph form) and the Gaussian update algebra the EKF and UKF share.

The small dense factorisations call LAPACK (dpotrf/dpotrs, dposv) directly: on 3x3 .. 6x6 matrices numpy's
and scipy's wrappers cost several times the routine itself, which matters for the EKF and UKF per-step
budgets (scripts/bench_filters.py measures them). For the same reason the per-step products use
``ndarray.dot`` rather than the ``@`` operator (the matmul ufunc's dispatch): the same BLAS call and the same
result, with less overhead on small operands.
"""

from __future__ import annotations

from functools import cache

import numpy as np
from scipy.linalg import lapack

from bench_models.models import MeasurementModel
from tracker_filters.filter_base import Filter


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

    S is factorised by Cholesky (LAPACK dposv: dpotrf and dpotrs in one call), so a non-positive-definite
    innovation covariance raises LinAlgError.
    """
    n = C.shape[0]
    B = np.empty((nu.shape[0], n + 1))
    B[:, 0:n] = C.T
    B[:, n] = nu
    _, sol, info = lapack.dposv(S, B, lower=1)
    if info != 0:
        raise np.linalg.LinAlgError(f"Cholesky factorisation failed (LAPACK info={info})")
    return sol[:, 0:n].T, float(nu.dot(sol[:, n]))


def joseph_update(
    x: np.ndarray, P: np.ndarray, nu: np.ndarray, H: np.ndarray, R: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float]:
    """Kalman measurement update with innovation nu and measurement matrix H (paper eq. 20).

    The covariance uses the Joseph form P = (I - K H) P (I - K H)^T + K R K^T, which stays symmetric
    positive semi-definite for any gain; the paper's P - K S K^T is algebraically equal at the optimal gain.
    Returns (x, P, NIS).
    """
    PHt = P.dot(H.T)
    S = H.dot(PHt)
    S += R
    K, nis = gain_and_nis(PHt, S, nu)
    IKH = _identity(x.shape[0]) - K.dot(H)
    return x + K.dot(nu), IKH.dot(P).dot(IKH.T) + K.dot(R).dot(K.T), nis


@cache
def _identity(n: int) -> np.ndarray:
    """The n x n identity, read-only (shared by every update)."""
    identity = np.eye(n)
    identity.flags.writeable = False
    return identity


class KalmanFilter(Filter):
    """Linear Kalman filter: x <- F x, P <- F P F^T + Q; Joseph-form update.

    Meant for linear models (``linear_models``): F = dynamics.transition_matrix, H = model.jacobian and
    the innovation z - h(x) (= z - H x for a linear model, angle-wrapped by the model's residual).
    """

    name = "kf"

    def _predict(self, dt: float) -> None:
        F = self.dynamics.transition_matrix(self.x, dt)
        Q = self.dynamics.process_noise(self.x, dt)
        self.x = F.dot(self.x)
        self.P = F.dot(self.P).dot(F.T) + Q

    def _update(self, z: np.ndarray, R: np.ndarray, model: MeasurementModel) -> float:
        H = model.jacobian(self.x, self.t)
        nu = model.residual(z, model.h(self.x, self.t))
        self.x, self.P, nis = joseph_update(self.x, self.P, nu, H, R)
        return nis
