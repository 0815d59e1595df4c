"""Cubature-quadrature Kalman filter (paper 004 eqs. 14–27; Bhaumik & Swati 2013).

The Gaussian integrals of the prediction and update steps are evaluated on the 2·n·n' points of
``cubature.cubature_quadrature_points``; order n' = 1 is the cubature Kalman filter (Arasaratnam & Haykin 2009).
Angle components of the measurement are averaged on the circle and differenced with wrapping.
"""

from __future__ import annotations

import numpy as np

from bench_models.models import DynamicsModel, MeasurementModel
from orbit_sim.angles import as_slice
from tracker_filters.covariance import ensure_pd
from tracker_filters.cubature import cubature_quadrature_points
from tracker_filters.filter_base import Filter
from tracker_filters.kf import cholesky_lower, gain_and_nis


def weighted_measurement_mean(Y: np.ndarray, weights: np.ndarray, angle_indices: list[int]) -> np.ndarray:
    """Σ w_j Y_j (paper 004 eq. 22), with angle components replaced by the weighted circular mean."""
    y = weights.dot(Y)
    if angle_indices:
        idx = as_slice(angle_indices)
        a = Y[:, idx]
        y[idx] = np.arctan2(weights.dot(np.sin(a)), weights.dot(np.cos(a)))
    return y


class CubatureQuadratureKF(Filter):
    """CQKF of radial order n' (``order``); 2·n·n' points, all weights positive."""

    name = "cqkf"

    def __init__(self, dynamics: DynamicsModel, order: int = 1) -> None:
        super().__init__(dynamics)
        if int(order) != order or order < 1:
            raise ValueError(f"cqkf: order must be an integer >= 1, got {order!r}")
        self.order = int(order)
        self._xi, self._w = cubature_quadrature_points(len(dynamics.labels), self.order)

    def _points(self) -> np.ndarray:
        """χ_j = S ξ_j + x with P = S Sᵀ (eqs. 14–15, 19–20); a P that fails Cholesky is repaired first."""
        try:
            S = cholesky_lower(self.P)
        except np.linalg.LinAlgError:
            self.P, _ = ensure_pd(self.P)
            self._warnings.append(f"{self.name}: covariance failed Cholesky before sampling; repaired")
            S = cholesky_lower(self.P)
        return self.x + self._xi.dot(S.T)

    def _predict(self, dt: float) -> None:
        """Eqs. 16–18: propagate the points, weighted mean and spread, plus Q."""
        Q = self.dynamics.process_noise(self.x, dt)
        chi = self.dynamics.propagate(self._points(), dt)
        self.x = self._w.dot(chi)
        D = chi - self.x
        self.P = (D.T * self._w).dot(D) + Q

    def _update(self, z: np.ndarray, R: np.ndarray, model: MeasurementModel) -> float:
        """Eqs. 19–27; returns the normalised innovation squared νᵀ P_yy⁻¹ ν."""
        chi = self._points()
        Y = model.h(chi, self.t)
        y_hat = weighted_measurement_mean(Y, self._w, model.angle_indices)
        dY = model.residual(Y, y_hat)
        dX = chi - self.x
        P_yy = (dY.T * self._w).dot(dY) + R
        P_xy = (dX.T * self._w).dot(dY)
        nu = model.residual(z, y_hat)
        K, nis = gain_and_nis(P_xy, P_yy, nu)
        self.x = self.x + K.dot(nu)
        self.P = self.P - K.dot(P_yy).dot(K.T)
        return nis
