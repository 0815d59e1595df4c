"""Image-plane motion models of a tracked star, state X = [x ẋ y ẏ]ᵀ (paper eq. 13; pixels and pixels/s), and
the measurement model z = H X + v, H = [[1 0 0 0], [0 0 1 0]] (eq. 19).

Constant velocity (eqs. 14–15): X_{n+1} = F X_n + E W_{n+1},

    F = [[1 Δt 0 0], [0 1 0 0], [0 0 1 Δt], [0 0 0 1]],   E = [[Δt²/2 0], [Δt 0], [0 Δt²/2], [0 Δt]],

with W = [a_x a_y]ᵀ zero-mean, uncorrelated, E[a_x²] = σ_x², E[a_y²] = σ_y² (eq. 17): an acceleration held
constant over each frame interval, Q = E diag(σ_x², σ_y²) Eᵀ (``kind="discrete"``, the paper's). The
continuous white-noise-acceleration variant (``kind="continuous"``, spectral density q per axis) has
Q = q [[Δt³/3 Δt²/2], [Δt²/2 Δt]] per axis.

Coordinated turn / constant-rate rotation (eq. 16): the velocity turns at the rate ω (rad/s) — the image of a
sky rotating about the boresight at ω moves on circles and its velocity turns at ω —

    Ẋ = A X + B W,   A = [[0 1 0 0], [0 0 0 −ω], [0 0 0 1], [0 ω 0 0]],   B = [[0 0], [1 0], [0 0], [0 1]],

discretised exactly: F = e^{AΔt} (scipy.linalg.expm) and Q = ∫_0^Δt e^{Aτ} B diag(q_x, q_y) Bᵀ e^{Aᵀτ} dτ (the
paper's q3 = q1 q2 q1ᵀ integrated; q2 = diag(0, q_x, 0, q_y)) by Van Loan's method (Van Loan 1978): with
M = [[−A, B Qc Bᵀ], [0, Aᵀ]] Δt and e^M = [[·, G12], [0, G22]], F = G22ᵀ and Q = F G12. For ω → 0 it tends to
the continuous constant-velocity model. (The paper's printed A and F carry typesetting slips — a 1 on the
diagonal, sign and row mix-ups; the matrices here are the standard coordinated-turn ones, and the tests check
F against the closed form

    F = [[1, sin ωΔt/ω, 0, −(1 − cos ωΔt)/ω], [0, cos ωΔt, 0, −sin ωΔt],
         [0, (1 − cos ωΔt)/ω, 1, sin ωΔt/ω],  [0, sin ωΔt, 0, cos ωΔt]].)
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from scipy.linalg import expm

H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])
"""Measurement matrix of eq. 19: the centroid (x, y)."""
B = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 0.0], [0.0, 1.0]])
"""Noise input of the continuous models: accelerations drive the velocities."""


def measurement_noise(sigma_px: float) -> np.ndarray:
    """R = σ² I₂ for a centroid noise of σ pixels per axis."""
    return float(sigma_px) ** 2 * np.eye(2)


def van_loan(A: np.ndarray, Qc: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(F, Q) of Ẋ = A X + w, E[w wᵀ] = Qc δ(t − s), over dt: F = e^{A dt}, Q = ∫ e^{Aτ} Qc e^{Aᵀτ} dτ."""
    n = A.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n], M[:n, n:], M[n:, n:] = -A, Qc, A.T
    G = expm(M * dt)
    F = G[n:, n:].T
    Q = F @ G[:n, n:]
    return F, 0.5 * (Q + Q.T)


class MotionModel(Protocol):
    def transition(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """(F, Q), each (4, 4), over an interval dt (s)."""


@dataclass(frozen=True)
class ConstantVelocity:
    """Constant velocity in the image (eqs. 14–15)."""

    sigma_a: float
    """Acceleration standard deviation σ_x = σ_y (px/s²) for ``kind="discrete"``; for ``"continuous"`` the
    square root of the spectral density q (px²/s³ = σ_a²)."""
    kind: str = "discrete"

    def __post_init__(self) -> None:
        if self.kind not in ("discrete", "continuous"):
            raise ValueError(f"kind must be 'discrete' or 'continuous', got {self.kind!r}")
        if self.sigma_a < 0:
            raise ValueError(f"sigma_a must be >= 0, got {self.sigma_a}")

    def transition(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        f = np.array([[1.0, dt], [0.0, 1.0]])
        if self.kind == "discrete":
            e = np.array([dt * dt / 2.0, dt])
            q = self.sigma_a ** 2 * np.outer(e, e)
        else:
            q = self.sigma_a ** 2 * np.array([[dt ** 3 / 3.0, dt ** 2 / 2.0], [dt ** 2 / 2.0, dt]])
        F, Q = np.zeros((4, 4)), np.zeros((4, 4))
        F[:2, :2] = F[2:, 2:] = f
        Q[:2, :2] = Q[2:, 2:] = q
        return F, Q


@dataclass(frozen=True)
class CoordinatedTurn:
    """Velocity turning at a known rate ω (eq. 16), continuous white acceleration noise of density q."""

    omega: float
    """Turn rate (rad/s); positive turns +x towards +y."""
    sigma_a: float
    """√q (q in px²/s³ per axis)."""

    def __post_init__(self) -> None:
        if self.sigma_a < 0:
            raise ValueError(f"sigma_a must be >= 0, got {self.sigma_a}")

    @property
    def A(self) -> np.ndarray:
        w = self.omega
        return np.array([[0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, -w], [0.0, 0.0, 0.0, 1.0], [0.0, w, 0.0, 0.0]])

    def transition(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        return van_loan(self.A, self.sigma_a ** 2 * B @ B.T, dt)


def turn_matrix(omega: float, dt: float) -> np.ndarray:
    """The closed-form coordinated-turn F (module docstring); ω = 0 gives constant velocity."""
    if abs(omega * dt) < 1e-12:
        return ConstantVelocity(0.0).transition(dt)[0]
    s, c = np.sin(omega * dt), np.cos(omega * dt)
    return np.array([[1.0, s / omega, 0.0, -(1.0 - c) / omega],
                     [0.0, c, 0.0, -s],
                     [0.0, (1.0 - c) / omega, 1.0, s / omega],
                     [0.0, s, 0.0, c]])
