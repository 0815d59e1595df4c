"""Interfaces every dynamics and measurement model implements, so any filter runs on any model.

The split follows Stone Soup: a dynamics model (transition), a measurement model (observation) and a
filter (predictor + updater) are separate objects. Filters only talk to models through these methods.

Array convention: a single state is shape (n,); a batch of states (sigma points, particles) is shape
(m, n), one state per row. Every method that takes ``x`` accepts both and returns the matching shape.

Optional methods, used when a model has them (looked up with ``getattr``/``hasattr``), never required:
  measurement ``hessian(x, t)`` (d, n, n)              second-order EKF (ekf.SecondOrderEKF)
  measurement ``derivatives(x, t)`` -> (h, H, Hessians)  the same in one pass (radar.GroundRadarModel)
  measurement ``h_series`` / ``jacobian_series(X, times)`` scans at different times, vectorised
  dynamics ``trajectory(x0, t0, times)`` -> (states, Phis)  (relinearisation.PassBatch fast path)
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, runtime_checkable

import numpy as np

from bench_engine.labels import angle_labels


def angle_components(labels: Sequence[str]) -> tuple[int, ...]:
    """Indices of the components of ``labels`` that are angles (bench_engine.labels.angle_labels)."""
    angles = angle_labels()
    return tuple(i for i, label in enumerate(labels) if label in angles)


def check_angles(model: MeasurementModel) -> None:
    """Raise ValueError if a measurement model's ``angle_indices`` are not the angles its labels name."""
    if tuple(model.angle_indices) != angle_components(model.labels):
        raise ValueError(
            f"{type(model).__name__} wraps components {tuple(model.angle_indices)} of "
            f"{tuple(model.labels)}, but the angles among them (bench_engine.labels) "
            f"are {angle_components(model.labels)}"
        )


@runtime_checkable
class DynamicsModel(Protocol):
    """State transition x(t + dt) = f(x(t), dt) with additive process noise of covariance Q(dt)."""

    labels: Sequence[str]
    """One name per state component, e.g. ("x", "y", "z", "vx", "vy", "vz")."""
    frame: str
    """Frame of the state vector, e.g. "eci" or "lvlh"."""

    def propagate(self, x: np.ndarray, dt: float) -> np.ndarray:
        """Propagate one state (n,) or a batch (m, n) by dt seconds (dt may be negative or zero)."""

    def transition_matrix(self, x: np.ndarray, dt: float) -> np.ndarray:
        """Jacobian d f(x, dt) / dx at the single state x, shape (n, n)."""

    def process_noise(self, x: np.ndarray, dt: float) -> np.ndarray:
        """Discrete process-noise covariance Q for a step of dt seconds, shape (n, n)."""


@runtime_checkable
class MeasurementModel(Protocol):
    """Observation z = h(x, t) + v, v ~ N(0, R); angle components are differenced with wrapping."""

    labels: Sequence[str]
    """One name per measurement component, e.g. ("range", "azimuth", "elevation")."""
    angle_indices: Sequence[int]
    """Indices of components that are angles and must be wrapped to (-pi, pi] when differenced."""

    def h(self, x: np.ndarray, t: float) -> np.ndarray:
        """Predicted measurement for one state (n,) -> (d,) or a batch (m, n) -> (m, d) at time t."""

    def jacobian(self, x: np.ndarray, t: float) -> np.ndarray:
        """d h / d x at the single state x, shape (d, n)."""

    def residual(self, z: np.ndarray, z_pred: np.ndarray) -> np.ndarray:
        """z - z_pred with angle components wrapped to (-pi, pi]; broadcasts over batches."""


@runtime_checkable
class ScanPositionModel(Protocol):
    """A measurement model from one scan of which a position follows (initialisation from a single scan:
    tracker_filters.initialisation.scan_position)."""

    def position_from_measurement(self, z: np.ndarray, t: float) -> np.ndarray:
        """The position (3,) that measurement z (its first three components) places the target at."""

    def position_jacobian(self, z: np.ndarray, t: float) -> np.ndarray:
        """d position_from_measurement / d z[:3], shape (3, 3)."""
