"""A dynamics model whose process noise is a given discrete covariance per step instead of a derived one.

Paper 001 (formation_pf) states its Q directly as a per-step diagonal; wrapping any dynamics model keeps
its transition and replaces only Q, scaled linearly with the step length (``per_step`` = Q at dt = 1 s
when ``reference_dt`` is 1).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bench_models.models import DynamicsModel


class GivenProcessNoise:
    """DynamicsModel delegating to ``base`` with Q(dt) = Q_ref * dt / reference_dt."""

    def __init__(self, base: DynamicsModel, Q_ref: np.ndarray, reference_dt: float = 1.0) -> None:
        n = len(base.labels)
        Q_ref = np.asarray(Q_ref, dtype=float)
        if Q_ref.shape != (n, n):
            raise ValueError(f"given Q must be {n}x{n} for states {list(base.labels)}, got {Q_ref.shape}")
        if reference_dt <= 0:
            raise ValueError(f"reference_dt must be > 0, got {reference_dt}")
        self.base = base
        self.Q_ref = Q_ref
        self.reference_dt = reference_dt
        self.labels: Sequence[str] = base.labels
        self.frame = base.frame

    def propagate(self, x: np.ndarray, dt: float) -> np.ndarray:
        return self.base.propagate(x, dt)

    def transition_matrix(self, x: np.ndarray, dt: float) -> np.ndarray:
        return self.base.transition_matrix(x, dt)

    def process_noise(self, x: np.ndarray, dt: float) -> np.ndarray:
        return self.Q_ref * (abs(dt) / self.reference_dt)
