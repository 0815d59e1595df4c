"""Inter-satellite-link measurement models on a relative LVLH state (papers 001 and 004).

The state is any relative state whose first three components are the internal-LVLH position
[x radial, y along-track, z orbit normal] (``orbit_sim.relative``): the 6-state and the 9-state (bias)
filters use the same models. Extra components (velocity, bias) do not enter h, their Jacobian columns are 0.
"""

from __future__ import annotations

import numpy as np

from bench_engine.labels import POSITION
from bench_models.models import angle_components
from orbit_sim.angles import wrapped_residual
from orbit_sim.relative import convention_matrix

TWO_PI = 2.0 * np.pi


class RangeAzElModel:
    """Range rho, azimuth alpha, elevation delta of the deputy seen from the chief, z = [rho, alpha, delta].

    The angles are defined in the axes of ``convention`` (the state stays internal; h maps it):
    - ``"along_radial"`` (paper 001, eq. 6 / fig. 3): X along-track, Y radial, Z = -orbit normal;
      alpha = atan2(Y, X) in [0, 2 pi) (the paper writes arctan(y/x) with range 0..2 pi), from the
      along-track axis towards radial; delta = asin(Z / rho) in [-pi/2, pi/2].
    - ``"radial_along_normal"`` (paper 004, eqs. 29-32): alpha = atan2(y, x) from the radial axis towards
      along-track, epsilon = asin(z / rho). Paper 004 orders its vector [alpha, epsilon, rho]; this model
      always returns [rho, alpha, delta] (the RangeAzEl message order), so permute paper 004's R (eq. 37)
      to diag(rho 1e-6 m^2, 7.6154e-5 rad^2, 7.6154e-5 rad^2).
    Azimuth is reported in [0, 2 pi) for both, as RangeAzEl.msg requires; residuals are wrapped.
    """

    labels = ("range", "azimuth", "elevation")
    angle_indices = angle_components(labels)

    def __init__(self, convention: str = "radial_along_normal") -> None:
        self.convention = convention
        self._M = convention_matrix(convention)

    def _axes(self, x: np.ndarray) -> np.ndarray:
        """Position(s) in the convention's axes, component first: shape (3, ...) for x (..., n)."""
        p = np.asarray(x, dtype=float)[..., 0:3]
        if p.ndim <= 2:  # tensordot's own product (M . p^T), without its axis bookkeeping: a filter's per-step cost
            return self._M.dot(p.T)
        return np.tensordot(self._M, p, axes=([1], [-1]))

    def h(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        """[rho, alpha, delta] for one state (n,) -> (3,) or a batch (m, n) -> (m, 3).

        Computed component-first (contiguous rows of m values; a batch's result is a transposed view):
        for the particle filters' m = 10 000 this is much cheaper than row-wise axes and ``np.mod``.
        """
        qx, qy, qz = self._axes(x)
        out = np.empty((3,) + np.shape(qx))
        rho = np.sqrt(qx * qx + qy * qy + qz * qz, out=out[0, ...])
        alpha = np.arctan2(qy, qx, out=out[1, ...])
        alpha += np.where(alpha < 0.0, TWO_PI, 0.0)
        alpha[alpha >= TWO_PI] = 0.0  # a tiny negative angle + 2 pi rounds to 2 pi
        np.arcsin(np.minimum(np.maximum(qz / rho, -1.0), 1.0), out=out[2, ...])  # np.clip, without its wrapper
        return out.T if out.ndim <= 2 else np.moveaxis(out, 0, -1)

    def jacobian(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        """Analytic d[rho, alpha, delta]/dx (3, n) at one state x (n,)."""
        x = np.asarray(x, dtype=float)
        q = self._axes(x)
        rho2 = float(q @ q)
        rho = np.sqrt(rho2)
        h2 = q[0] ** 2 + q[1] ** 2
        h = np.sqrt(h2)
        dq = np.array(
            [
                q / rho,
                [-q[1] / h2, q[0] / h2, 0.0],
                [-q[0] * q[2] / (rho2 * h), -q[1] * q[2] / (rho2 * h), h / rho2],
            ]
        )
        H = np.zeros((3, x.shape[-1]))
        H[:, 0:3] = dq @ self._M
        return H

    def jacobian_series(self, x: np.ndarray, times: np.ndarray) -> np.ndarray:
        """``jacobian`` of every state of a series x (K, n) at once, shape (K, 3, n) (the model is time-free)."""
        x = np.asarray(x, dtype=float)
        q = np.moveaxis(self._axes(x), 0, -1)  # (K, 3)
        rho2 = np.sum(q * q, axis=1)
        rho, h2 = np.sqrt(rho2), q[:, 0] ** 2 + q[:, 1] ** 2
        h = np.sqrt(h2)
        zero = np.zeros_like(h)
        dq = np.stack(
            [
                q / rho[:, None],
                np.stack([-q[:, 1] / h2, q[:, 0] / h2, zero], axis=1),
                np.stack([-q[:, 0] * q[:, 2] / (rho2 * h), -q[:, 1] * q[:, 2] / (rho2 * h), h / rho2], axis=1),
            ],
            axis=1,
        )
        H = np.zeros((len(x), 3, x.shape[-1]))
        H[:, :, 0:3] = dq @ self._M
        return H

    def residual(self, z: np.ndarray, z_pred: np.ndarray) -> np.ndarray:
        """z - z_pred with the angles wrapped to (-pi, pi]."""
        return wrapped_residual(z, z_pred, self.angle_indices)


class RelativePositionModel:
    """Linear z = [x y z] = H x, H = [I3 0] (paper 004 eq. 28), for a state of any length >= 3.

    The same object serves the sensor (6-state truth) and 6- or 9-state filters: H takes its width from x.
    """

    labels = POSITION
    angle_indices: tuple[int, ...] = ()

    def h(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        """Relative position of one state (n,) -> (3,) or a batch (m, n) -> (m, 3)."""
        return np.array(np.asarray(x, dtype=float)[..., 0:3])

    def jacobian(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        """H = [I3 0], shape (3, len(x))."""
        return np.eye(3, np.shape(x)[-1])

    def residual(self, z: np.ndarray, z_pred: np.ndarray) -> np.ndarray:
        """Plain difference z - z_pred."""
        return wrapped_residual(z, z_pred, self.angle_indices)
