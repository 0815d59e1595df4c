"""Extended Kalman filters: the paper's first-order EKF (paper 000, eqs. 19-21) and a second-order one.

Prediction propagates the mean through the nonlinear dynamics, x(k|k-1) = f(x(k-1|k-1)), and the
covariance through the dynamics' Jacobian F evaluated at x(k-1|k-1): P(k|k-1) = F P F^T + Q (eq. 19).
The update linearises h at x(k|k-1) (eq. 21), forms the angle-wrapped innovation B = y - h(x(k|k-1)) and
applies the gain of eq. 20 with the Joseph-form covariance (kf.joseph_update) instead of P - K S K^T.

Both accept ``relinearise`` (a growth factor > 1; 0 = off, the paper's filter): Gauss-Newton re-solves of
all scans since the first on a geometric schedule (relinearisation.py), for deterministic process models.
"""

from __future__ import annotations

import numpy as np

from bench_models.models import DynamicsModel, MeasurementModel
from tracker_filters.kf import KalmanFilter, joseph_update
from tracker_filters.relinearisation import Relinearising


def second_order_moments(hessians: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of the quadratic terms 1/2 dx^T H_i'' dx, dx ~ N(0, P), for Hessians (d, m, m):
    bias_i = 1/2 tr(H_i'' P) (d,) and B_ij = 1/2 tr(H_i'' P H_j'' P) (d, d).

    Hessians that vanish outside the first m of n state components need only that block of P (m, m): the
    radar's range, azimuth and elevation have m = 3."""
    d, m = hessians.shape[0:2]
    HP = hessians @ P
    flat = HP.reshape(d, m * m)
    return 0.5 * flat[:, :: m + 1].sum(axis=1), 0.5 * flat.dot(HP.transpose(0, 2, 1).reshape(d, m * m).T)


class ExtendedKalmanFilter(Relinearising, KalmanFilter):
    """EKF: the Kalman filter's update (eq. 20) with a nonlinear mean prediction (eq. 19)."""

    name = "ekf"

    def __init__(self, dynamics: DynamicsModel, relinearise: float = 0.0, relinearise_from: int = 100) -> None:
        super().__init__(dynamics)
        self._setup_relinearisation(relinearise, relinearise_from)

    def _predict(self, dt: float) -> None:
        F = self.dynamics.transition_matrix(self.x, dt)
        Q = self.dynamics.process_noise(self.x, dt)
        self.x = self.dynamics.propagate(self.x, dt)
        self.P = F.dot(self.P).dot(F.T) + Q


class SecondOrderEKF(ExtendedKalmanFilter):
    """EKF with the Gaussian second-order measurement update (Athans, Wishner & Bertolini 1968; Gelb 1974, 6.1).

    With H_i'' the Hessian of measurement component i at the predicted state (``model.hessian``):
        y = h(x) + 1/2 sum_i e_i tr(H_i'' P)                      (mean of h to second order)
        S = H P H^T + R + B,   B_ij = 1/2 tr(H_i'' P H_j'' P)     (variance of the quadratic terms)
    and the update of eq. 20 with the effective noise R + B. On a linear model the Hessians vanish and the
    filter is the EKF. The prediction stays first-order: over one 0.1 s step the orbit dynamics' second-order
    terms are negligible against the measurement's.

    A model may offer ``derivatives(x, t) -> (h (d,), H (d, n), Hessians (d, m, m))``, the Hessians over
    the first m state components (zero elsewhere), in place of ``h``, ``jacobian`` and ``hessian``: one
    shared pass, and the moments over the m x m block of P (bench_models.radar: m = 3).
    """

    name = "ekf2"

    def _update(self, z: np.ndarray, R: np.ndarray, model: MeasurementModel) -> float:
        y, H, hessians = self._derivatives(model)
        m = hessians.shape[-1]
        bias, B = second_order_moments(hessians, self.P[0:m, 0:m])
        nu = model.residual(z, y + bias)
        self.x, self.P, nis = joseph_update(self.x, self.P, nu, H, R + B)
        return nis

    def _derivatives(self, model: MeasurementModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """h, Jacobian and Hessians (d, m, m) at the predicted state, over its first m components.

        From the model's ``derivatives(x, t)`` when it has one (one shared pass), else from ``h``,
        ``jacobian`` and ``hessian`` (m = n)."""
        derivatives = getattr(model, "derivatives", None)
        if derivatives is not None:
            return derivatives(self.x, self.t)
        hessian = getattr(model, "hessian", None)
        if hessian is None:
            raise TypeError(f"{self.name}: the measurement model {type(model).__name__} has no hessian(x, t)")
        return model.h(self.x, self.t), model.jacobian(self.x, self.t), hessian(self.x, self.t)
