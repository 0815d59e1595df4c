"""Cubature-quadrature points for Gaussian integrals (paper 004, CQKF set-up; Bhaumik & Swati 2013).

∫ f(x) N(x; 0, I_n) dx is split into a radius and a direction. With x = r·s, |s| = 1, λ = r²/2:

    ∫ f N dx = 1/Γ(n/2) ∫_0^∞ λ^(n/2 − 1) e^(−λ) ⟨f(√(2λ) s)⟩_s dλ,   ⟨·⟩_s: mean over the unit sphere.

The sphere mean uses the third-degree spherical rule (the 2n points ±e_j, weights 1/(2n)); the radial
integral uses the order-n' generalized Gauss–Laguerre rule with α = n/2 − 1 (nodes λ_i, weights A_i).
The product rule has 2·n·n' points ξ = √(2λ_i)·(±e_j) with weights A_i / (2n·Γ(n/2)); it is exact for
every polynomial of degree ≤ 3 and for the radial moments E|x|^(2k), k ≤ 2n' − 1 (E|x|⁴ needs n' ≥ 2).
n' = 1 gives λ_1 = n/2: the standard cubature Kalman filter points ±√n·e_j with weights 1/(2n).
"""

from __future__ import annotations

import numpy as np
from scipy.special import gamma, roots_genlaguerre


def radial_rule(n: int, order: int) -> tuple[np.ndarray, np.ndarray]:
    """Generalized Gauss–Laguerre nodes λ_i and weights A_i for ∫_0^∞ λ^(n/2−1) e^(−λ) g(λ) dλ."""
    if n < 1 or order < 1:
        raise ValueError(f"need state dimension n >= 1 and order >= 1, got n={n}, order={order}")
    nodes, weights = roots_genlaguerre(order, n / 2.0 - 1.0)
    return np.asarray(nodes, dtype=float), np.asarray(weights, dtype=float)


def cubature_quadrature_points(n: int, order: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Unit points ξ (2·n·order, n) and weights (2·n·order,) for N(0, I_n); weights sum to 1.

    A sample for N(m, S Sᵀ) is m + S ξ_j (paper 004 eqs. 15 and 20).
    """
    nodes, radial_weights = radial_rule(n, order)
    directions = np.vstack([np.eye(n), -np.eye(n)])
    points = (np.sqrt(2.0 * nodes)[:, None, None] * directions[None, :, :]).reshape(-1, n)
    weights = np.repeat(radial_weights / (2.0 * n * gamma(n / 2.0)), 2 * n)
    return points, weights
