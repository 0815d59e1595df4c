"""Wiener-process-acceleration (white-jerk) kinematics: paper 002, eqs. 16-26.

Per axis the state is (position, velocity, acceleration) driven by white jerk of spectral density q
[m^2/s^5]:  d/dt [p v a] = F [p v a] + [0 0 1] w,  F = [[0 1 0], [0 0 1], [0 0 0]],  E[w w'] = q delta.
The discrete model over a step dt is

    A(dt) = expm(F dt) = [[1, dt, dt^2/2], [0, 1, dt], [0, 0, 1]]
    Q(dt) = q [[dt^5/20, dt^4/8, dt^3/6], [dt^4/8, dt^3/3, dt^2/2], [dt^3/6, dt^2/2, dt]]

(the standard integral of expm(F s) G G' expm(F s)' over the step; the paper's printed Q has index typos).
The three axes are independent and identical, so with the state ordered (positions, velocities,
accelerations) the 9-state matrices are Kronecker products with I_3. The model is purely kinematic: it
knows nothing of gravity, which is what paper 002 wants (a model-free velocity from GNSS positions).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.linalg import expm

F_AXIS = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
"""Per-axis system matrix of (p, v, a)."""


def axis_transition(dt: float) -> np.ndarray:
    """A(dt) = expm(F dt) for one axis (3, 3)."""
    return expm(F_AXIS * dt)


def axis_noise(q: float, dt: float) -> np.ndarray:
    """Q(dt) for one axis (3, 3): the white-jerk integral in closed form (|dt| is used)."""
    h = abs(dt)
    return q * np.array(
        [[h**5 / 20.0, h**4 / 8.0, h**3 / 6.0], [h**4 / 8.0, h**3 / 3.0, h**2 / 2.0], [h**3 / 6.0, h**2 / 2.0, h]]
    )


class WhiteJerkDynamics:
    """Nine-state (or 3 x any dimension) white-jerk model on named components, for any linear filter.

    ``labels`` name the state: 3 positions, 3 velocities, 3 accelerations, in that order (e.g. the GRACE
    baseline ``bx by bz bvx bvy bvz bax bay baz``). A and Q are cached per step dt: the filters ask at every
    step, usually with the same dt.
    """

    def __init__(self, q: float, labels: Sequence[str], frame: str = "eci") -> None:
        if not np.isfinite(q) or q < 0.0:
            raise ValueError(f"white-jerk spectral density q must be finite and >= 0, got {q}")
        if len(labels) % 3 or not labels:
            raise ValueError(
                f"white-jerk labels come in three equal blocks (positions, velocities, "
                f"accelerations), got {list(labels)}"
            )
        self.q = float(q)
        self.labels = tuple(labels)
        self.frame = frame
        self.dim = len(labels) // 3
        self._cache: dict[float, tuple[np.ndarray, np.ndarray]] = {}

    def _matrices(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        key = float(dt)
        pair = self._cache.get(key)
        if pair is None:
            if len(self._cache) > 64:
                self._cache.clear()
            eye = np.eye(self.dim)
            pair = (np.kron(axis_transition(key), eye), np.kron(axis_noise(self.q, key), eye))
            for m in pair:
                m.setflags(write=False)
            self._cache[key] = pair
        return pair

    def propagate(self, x: np.ndarray, dt: float) -> np.ndarray:
        return np.asarray(x, dtype=float) @ self._matrices(dt)[0].T

    def transition_matrix(self, x: np.ndarray, dt: float) -> np.ndarray:
        return self._matrices(dt)[0]

    def process_noise(self, x: np.ndarray, dt: float) -> np.ndarray:
        return self._matrices(dt)[1]
