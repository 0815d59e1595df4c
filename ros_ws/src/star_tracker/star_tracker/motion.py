"""Image-plane motion models of a tracked star, state X = [x ẋ y ẏ]ᵀ (paper eq. 13; pixels and pixels/s), and
the measurement model z = H X + v, H = [[1 0 0 0], [0 0 1 0]] (eq. 19).

Constant velocity (eqs. 14–15): X_{n+1} = F X_n + E W_{n+1},

    F = [[1 Δt 0 0], [0 1 0 0], [0 0 1 Δt], [0 0 0 1]],   E = [[Δt²/2 0], [Δt 0], [0 Δt²/2], [0 Δt]],

with W = [a_x a_y]ᵀ zero-mean, uncorrelated, E[a_x²] = σ_x², E[a_y²] = σ_y² (eq. 17): an acceleration held
constant over each frame interval, Q = E diag(σ_x², σ_y²) Eᵀ (``kind="discrete"``, the paper's; its eq. 14
prints E's Δt²/2 as 1/(2Δt²), a slip: eq. 15 has Δt²/2). The
continuous white-noise-acceleration variant (``kind="continuous"``, spectral density q per axis) has
Q = q [[Δt³/3 Δt²/2], [Δt²/2 Δt]] per axis.

Coordinated turn / constant-rate rotation (eq. 16): the velocity turns at the rate ω (rad/s) — the image of a
sky rotating about the boresight at ω moves on circles and its velocity turns at ω —

    Ẋ = A X + B W,   A = [[0 1 0 0], [0 0 0 −ω], [0 0 0 1], [0 ω 0 0]],   B = [[0 0], [1 0], [0 0], [0 1]],

discretised exactly: F = e^{AΔt} and Q = ∫_0^Δt e^{Aτ} B diag(q, q) Bᵀ e^{Aᵀτ} dτ (the paper's q3 = q1 q2 q1ᵀ
integrated; q2 = diag(0, q, 0, q)), both in closed form (:func:`turn_matrix`, :func:`turn_noise`; for a
generic model, :func:`van_loan` gives them from scipy.linalg.expm by Van Loan's method (Van Loan 1978): with
M = [[−A, B Qc Bᵀ], [0, Aᵀ]] Δt and e^M = [[·, G12], [0, G22]], F = G22ᵀ and Q = F G12; the tests check the
closed forms against it and against a quadrature of the paper's integral). For ω → 0 it tends to the
continuous constant-velocity model. (The paper's printed A and F carry typesetting slips — a 1 on the
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


def image_turn(angle: float) -> np.ndarray:
    """T (4, 4) turning a track state [x ẋ y ẏ] by ``angle`` (rad, +x towards +y) about the image origin: the
    paper's eq. 18 compensation of a measured rotation of the image (positions and velocities turn alike)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, -s, 0.0], [0.0, c, 0.0, -s], [s, 0.0, c, 0.0], [0.0, s, 0.0, c]])


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
            q = self.sigma_a**2 * np.outer(e, e)
        else:
            q = self.sigma_a**2 * np.array([[dt**3 / 3.0, dt**2 / 2.0], [dt**2 / 2.0, dt]])
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
        """F = e^{AΔt} and Q in closed form (module docstring); tests check both against expm/Van Loan."""
        return turn_matrix(self.omega, dt), turn_noise(self.omega, dt, self.sigma_a**2)


def _turn_terms(omega: float, dt: float) -> tuple[float, float, float]:
    """(x − sin x)/ω³, (x − sin x)/ω², (1 − cos x)/ω² with x = ωΔt, by their series when x is small (the
    differences cancel) and exactly otherwise."""
    x = omega * dt
    if abs(x) < 1e-2:
        x2 = x * x
        a = dt**3 * (1.0 / 6.0 - x2 / 120.0 + x2 * x2 / 5040.0)  # (x − sin x)/ω³
        c = dt**2 * (0.5 - x2 / 24.0 + x2 * x2 / 720.0)  # (1 − cos x)/ω²
        return a, a * omega, c
    return (x - np.sin(x)) / omega**3, (x - np.sin(x)) / omega**2, (1.0 - np.cos(x)) / omega**2


def turn_noise(omega: float, dt: float, q: float) -> np.ndarray:
    """Q = q ∫_0^Δt g1 g1ᵀ + g2 g2ᵀ dτ of the coordinated turn, g1, g2 the columns of e^{Aτ} for the two
    velocity inputs: with s3 = (x − sin x)/ω³, s2 = (x − sin x)/ω², c2 = (1 − cos x)/ω², x = ωΔt,

        Q = q [[2 s3, c2, 0, s2], [c2, Δt, −s2, 0], [0, −s2, 2 s3, c2], [s2, 0, c2, Δt]]

    (ω → 0: the continuous constant-velocity Q)."""
    s3, s2, c2 = _turn_terms(omega, dt)
    return q * np.array([[2 * s3, c2, 0.0, s2], [c2, dt, -s2, 0.0], [0.0, -s2, 2 * s3, c2], [s2, 0.0, c2, dt]])


def turn_matrix(omega: float, dt: float) -> np.ndarray:
    """The closed-form coordinated-turn F (module docstring), written with the terms of :func:`_turn_terms`
    so that it stays accurate as ω → 0 (ω = 0 gives constant velocity)."""
    _, s2, c2 = _turn_terms(omega, dt)
    sin_w = dt - omega * s2  # sin x / ω
    cos_1 = omega * c2  # (1 − cos x) / ω
    s, c = omega * sin_w, 1.0 - omega * cos_1
    return np.array([[1.0, sin_w, 0.0, -cos_1], [0.0, c, 0.0, -s], [0.0, cos_1, 1.0, sin_w], [0.0, s, 0.0, c]])
