"""Unscented Kalman filter with scaled sigma points (paper 000, eqs. 22-34), additive noise.

Predict: sigma points of (x, P) are propagated through the dynamics as one (2n + 1, n) batch (eq. 24);
their weighted mean and covariance plus Q give the prediction (eqs. 25-26).
Update: sigma points are redrawn from the predicted (x, P), which includes Q, and mapped through h
(eq. 28); the predicted measurement is their angle-aware weighted mean (eq. 29), then P_yy + R, the
cross-covariance P_xy and the gain K = P_xy P_yy^-1 (eqs. 30-32), x += K (z - y), P -= K P_yy K^T
(eqs. 33-34). Redrawing is what makes the filter exactly a Kalman filter on linear models; reusing the
propagated points (as eq. 28 literally reads) would leave Q out of P_xy. P_yy is factorised by Cholesky.

``relinearise`` (a growth factor > 1; 0 = off, the paper's filter): Gauss-Newton re-solves of all scans since
the first on a geometric schedule (relinearisation.py), for deterministic process models.
"""

from __future__ import annotations

import numpy as np

from bench_models.models import DynamicsModel, MeasurementModel
from tracker_filters.filter_base import Filter
from tracker_filters.kf import gain_and_nis
from tracker_filters.relinearisation import Relinearising
from tracker_filters.sigma_points import ScaledSigmaPoints


class UnscentedKalmanFilter(Relinearising, Filter):
    """UKF with L = n, scaled sigma points (alpha, beta = 2, kappa = 0 by default)."""

    name = "ukf"

    def __init__(
        self,
        dynamics: DynamicsModel,
        alpha: float = 1.0,
        beta: float = 2.0,
        kappa: float = 0.0,
        relinearise: float = 0.0,
        relinearise_from: int = 100,
    ) -> None:
        super().__init__(dynamics)
        self.points = ScaledSigmaPoints(len(dynamics.labels), alpha, beta, kappa)
        self._setup_relinearisation(relinearise, relinearise_from)

    def _sigma_points(self) -> np.ndarray:
        """Sigma points of (x, P); a P that Cholesky rejects is repaired (and reported) first."""
        try:
            return self.points.generate(self.x, self.P)
        except np.linalg.LinAlgError:
            self.P = self._repaired(self.P, "before drawing sigma points")
            return self.points.generate(self.x, self.P)

    def _predict(self, dt: float) -> None:
        X = self.dynamics.propagate(self._sigma_points(), dt)
        x = self.points.mean(X)
        self.P = self.points.covariance(X - x) + self.dynamics.process_noise(self.x, dt)
        self.x = x

    def _update(self, z: np.ndarray, R: np.ndarray, model: MeasurementModel) -> float:
        X = self._sigma_points()
        Y = model.h(X, self.t)
        y = self.points.mean(Y, model.residual)
        DY = model.residual(Y, y)
        Pyy = self.points.covariance(DY) + R
        Pxy = self.points.covariance(X - self.x, DY)
        nu = model.residual(z, y)
        K, nis = gain_and_nis(Pxy, Pyy, nu)
        self.x = self.x + K @ nu
        self.P = self.P - K @ Pyy @ K.T
        return nis
