"""Scaled symmetric sigma points and their weights (paper 000, eqs. 23 and 27; Julier 2002, Wan & van der Merwe).

With L = n state dimensions and lambda = alpha^2 (n + kappa) - n (the paper prints lambda = L - alpha^2,
a garbling of this standard definition), the 2n + 1 points are x and x +/- gamma (columns of sqrt(P)),
gamma = sqrt(n + lambda), with weights
    W0_m = lambda / (n + lambda),   W0_c = W0_m + 1 - alpha^2 + beta,   Wi_m = Wi_c = 1 / (2 (n + lambda)).
sqrt(P) is the lower Cholesky factor.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from tracker_filters.kf import cholesky_lower

Residual = Callable[[np.ndarray, np.ndarray], np.ndarray]


class ScaledSigmaPoints:
    """Point generator and weighted statistics for the scaled unscented transform of an n-vector."""

    def __init__(self, n: int, alpha: float, beta: float = 2.0, kappa: float = 0.0) -> None:
        if not (isinstance(n, (int, np.integer)) and n >= 1):
            raise ValueError(f"state dimension must be a positive integer, got {n}")
        if not 0.0 < alpha <= 1.0:
            raise ValueError(f"alpha must be in (0, 1], got {alpha}")
        if not beta >= 0.0:
            raise ValueError(f"beta must be >= 0, got {beta}")
        if not n + kappa > 0.0:
            raise ValueError(f"kappa must be > -n = {-n}, got {kappa}")
        self.n = int(n)
        self.alpha, self.beta, self.kappa = float(alpha), float(beta), float(kappa)
        lam = alpha * alpha * (n + kappa) - n
        self.gamma = math.sqrt(n + lam)
        self.wm = np.full(2 * n + 1, 0.5 / (n + lam))
        self.wc = self.wm.copy()
        self.wm[0] = lam / (n + lam)
        self.wc[0] = self.wm[0] + 1.0 - alpha * alpha + beta

    def generate(self, x: np.ndarray, P: np.ndarray) -> np.ndarray:
        """Sigma points (2n + 1, n), one per row, from mean x (n,) and covariance P (paper eq. 23)."""
        spread = self.gamma * cholesky_lower(P).T
        return x + np.concatenate((np.zeros((1, self.n)), spread, -spread))

    def mean(self, Y: np.ndarray, residual: Residual | None = None) -> np.ndarray:
        """Weighted mean of transformed points Y (2n + 1, d) (paper eqs. 25 and 29).

        Accumulated as offsets from the central point, Y0 + sum W_i (Y_i - Y0), with ``residual`` forming
        the offsets: angle components then average without 0 / 2 pi wrap artefacts, and the large
        opposite-signed weights of a small alpha do not cancel absolute values of ~7e6 m.
        """
        offsets = Y - Y[0] if residual is None else residual(Y, Y[0])
        return Y[0] + self.wm @ offsets

    def covariance(self, D: np.ndarray, E: np.ndarray | None = None) -> np.ndarray:
        """sum W_i^c D_i E_i^T of deviations D (2n + 1, a) and E (2n + 1, b); E = D when omitted (eqs. 26, 30, 31)."""
        return (D.T * self.wc) @ (D if E is None else E)
