"""Measurement models defined on named state components, so a sensor and a filter with different state
layouts share one model.

The truth of a two-satellite study publishes 18 components (both satellites and their baseline); a filter of
that study may estimate 9 (position, velocity and acceleration of the baseline). A model here names the
components it reads (``x1``, ``bvx``, ...) and is *bound* to a layout with ``for_state(labels)``: the sensor
binds it to the truth's labels, each filter to its own. An unbound model raises on use.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


class UnboundModel(RuntimeError):
    """A labelled model was used before ``for_state`` gave it a state layout."""


def _indices(wanted: Sequence[str], labels: Sequence[str], what: str) -> list[int]:
    missing = [w for w in wanted if w not in labels]
    if missing:
        raise ValueError(
            f"{what} reads state components {missing}, which a state labelled {list(labels)} does not have"
        )
    return [list(labels).index(w) for w in wanted]


class ComponentModel:
    """z = H x + v, H selecting the named components: a position fix (``x1 y1 z1``), a baseline (``bx by bz``),
    or positions with numerically differentiated velocities (paper 002, eq. 29)."""

    angle_indices: Sequence[int] = ()

    def __init__(self, components: Sequence[str], state_labels: Sequence[str] | None = None) -> None:
        self.labels = tuple(components)
        self.state_labels = None if state_labels is None else tuple(state_labels)
        self._idx = None if state_labels is None else _indices(self.labels, state_labels, "the measurement")

    def for_state(self, labels: Sequence[str]) -> ComponentModel:
        return ComponentModel(self.labels, labels)

    def _index(self) -> list[int]:
        if self._idx is None:
            raise UnboundModel(f"measurement of {list(self.labels)} has no state layout: call for_state(labels)")
        return self._idx

    def h(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        return np.asarray(x, dtype=float)[..., self._index()]

    def jacobian(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        H = np.zeros((len(self.labels), len(self.state_labels or ())))
        H[np.arange(len(self.labels)), self._index()] = 1.0
        return H

    def residual(self, z: np.ndarray, z_pred: np.ndarray) -> np.ndarray:
        return np.asarray(z, dtype=float) - np.asarray(z_pred, dtype=float)


class RangeRateModel:
    """Inter-satellite range and range rate from a baseline position b and velocity w (paper 002, eq. 27):
    rho = |b|, rho_dot = b . w / |b|. ``components`` chooses which of ("range", "range_rate") are measured."""

    angle_indices: Sequence[int] = ()

    def __init__(
        self,
        position: Sequence[str],
        velocity: Sequence[str],
        components: Sequence[str] = ("range", "range_rate"),
        state_labels: Sequence[str] | None = None,
    ) -> None:
        bad = [c for c in components if c not in ("range", "range_rate")]
        if bad or not components:
            raise ValueError(f"range/range-rate components must be 'range' and/or 'range_rate', got {components}")
        self.position, self.velocity, self.labels = tuple(position), tuple(velocity), tuple(components)
        self.state_labels = None if state_labels is None else tuple(state_labels)
        self._idx = (
            None
            if state_labels is None
            else (
                _indices(self.position, state_labels, "the range"),
                _indices(self.velocity, state_labels, "the range"),
            )
        )

    def for_state(self, labels: Sequence[str]) -> RangeRateModel:
        return RangeRateModel(self.position, self.velocity, self.labels, labels)

    def _parts(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self._idx is None:
            raise UnboundModel("range/range-rate model has no state layout: call for_state(labels)")
        x = np.asarray(x, dtype=float)
        return x[..., self._idx[0]], x[..., self._idx[1]]

    def h(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        b, w = self._parts(x)
        rho = np.linalg.norm(b, axis=-1)
        values = {"range": rho, "range_rate": np.sum(b * w, axis=-1) / rho}
        return np.stack([values[c] for c in self.labels], axis=-1)

    def jacobian(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        """d rho / d b = u; d rho_dot / d b = (w - rho_dot u) / rho, d rho_dot / d w = u (u = b / rho)."""
        b, w = self._parts(x)
        rho = float(np.linalg.norm(b))
        u = b / rho
        rows = {"range": (u, np.zeros(3)), "range_rate": ((w - (u @ w) * u) / rho, u)}
        H = np.zeros((len(self.labels), len(self.state_labels)))
        for i, c in enumerate(self.labels):
            H[i, self._idx[0]], H[i, self._idx[1]] = rows[c]
        return H

    def residual(self, z: np.ndarray, z_pred: np.ndarray) -> np.ndarray:
        return np.asarray(z, dtype=float) - np.asarray(z_pred, dtype=float)
