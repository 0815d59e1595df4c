"""The Cramér-Rao bound of one frame's attitude from its star centroids (the Wahba problem's Fisher information).

A star seen along b = A r (camera frame, attitude.py's convention) is measured as its tangent-plane position
t = (b_x / b_z, b_y / b_z) with independent noise sigma per axis (tangent units: the centroid noise in pixels
over the focal length, camera.py). For the attitude error δθ (camera frame, Â = exp(−[δθ×]) A) the perturbed
direction is b − δθ × b, so ∂b/∂δθ = [b×] and, with b = (t_x, t_y, 1) (t is scale-free),

    H_i = ∂t_i/∂δθ = [[1, 0, −t_x], [0, 1, −t_y]] [b_i×],     J = Σ_i H_iᵀ H_i / σ²,

the Fisher information of the frame; J⁻¹ bounds any unbiased attitude estimate from these centroids. Near the
boresight (|t| ≪ 1) it is the QUEST measurement model's Σ (I − b bᵀ)/σ² (attitude.wahba). The bound is
evaluated at the measured centroids (their 0.1-pixel noise moves it by a negligible amount) and takes every
centroid for a star: a false star would add information that does not exist (the study's default has none).
"""

from __future__ import annotations

import numpy as np

from star_tracker.attitude import skew


def centroid_jacobians(xy: np.ndarray) -> np.ndarray:
    """H_i (N, 2, 3) of stars at tangent-plane positions xy (N, 2) (module docstring)."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    D = np.zeros((len(xy), 2, 3))
    D[:, 0, 0] = D[:, 1, 1] = 1.0
    D[:, :, 2] = -xy
    b = np.column_stack([xy, np.ones(len(xy))])
    return D @ np.array([skew(v) for v in b])


def attitude_information(xy: np.ndarray, sigma: float) -> np.ndarray:
    """J = Σ H_iᵀ H_i / σ² (3, 3) of one frame's centroids xy (N, 2), noise sigma per axis (tangent units)."""
    H = centroid_jacobians(xy)
    return np.einsum("nki,nkj->ij", H, H) / sigma**2
