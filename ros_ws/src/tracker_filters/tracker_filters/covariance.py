"""Covariance hygiene shared by all Gaussian filters."""

from __future__ import annotations

import numpy as np
from scipy.linalg.lapack import dpotrf


def ensure_pd(P: np.ndarray, rel_floor: float = 1e-12) -> tuple[np.ndarray, bool]:
    """Return a symmetric positive-definite version of P and whether it had to be repaired.

    P is always symmetrised. If its Cholesky factorisation fails, eigenvalues below
    ``rel_floor * max(|eig|)`` (or any non-finite entry) are lifted to that floor.
    """
    P = 0.5 * (P + P.T)
    if dpotrf(P, lower=1, clean=0)[1] == 0:  # LAPACK directly: numpy's wrapper dominates at 6x6
        return P, False
    if not np.all(np.isfinite(P)):
        raise np.linalg.LinAlgError("covariance has non-finite entries")
    w, V = np.linalg.eigh(P)
    floor = rel_floor * max(float(np.max(np.abs(w))), 1e-300)
    w = np.maximum(w, floor)
    return (V * w) @ V.T, True
