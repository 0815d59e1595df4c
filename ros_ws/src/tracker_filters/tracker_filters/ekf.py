"""Extended Kalman filter (paper 000, eqs. 19-21).

Prediction propagates the mean through the nonlinear dynamics, x(k|k-1) = f(x(k-1|k-1)), and the
covariance through the dynamics' Jacobian F evaluated at x(k-1|k-1): P(k|k-1) = F P F^T + Q (eq. 19).
The update linearises h at x(k|k-1) (eq. 21), forms the angle-wrapped innovation B = y - h(x(k|k-1)) and
applies the gain of eq. 20 with the Joseph-form covariance (kf.joseph_update) instead of P - K S K^T.
"""
from __future__ import annotations

from tracker_filters.kf import KalmanFilter


class ExtendedKalmanFilter(KalmanFilter):
    """EKF: the Kalman filter's update (eq. 20) with a nonlinear mean prediction (eq. 19)."""

    name = "ekf"

    def _predict(self, dt: float) -> None:
        F = self.dynamics.transition_matrix(self.x, dt)
        Q = self.dynamics.process_noise(self.x, dt)
        self.x = self.dynamics.propagate(self.x, dt)
        self.P = F @ self.P @ F.T + Q
