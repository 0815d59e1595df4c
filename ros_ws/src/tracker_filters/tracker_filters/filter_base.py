"""What every filter shares: its state, the guarded measurement step, and the warnings it raises.

A concrete filter (``kf.py``, ``ekf.py``, ``ukf.py``, ...) implements ``_predict`` and ``_update``. The base
class owns the checks the bench promises: a NaN/inf or out-of-order measurement is rejected with a reason
and leaves the filter untouched; a covariance that loses positive-definiteness is repaired and reported.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from scipy.special import chdtri

from bench_models.models import DynamicsModel, MeasurementModel
from tracker_filters.covariance import ensure_pd


@dataclass
class StepResult:
    """Outcome of one ``Filter.process`` call."""

    accepted: bool
    reason: str = ""
    """Why the measurement was rejected (empty when accepted)."""
    nis: float = float("nan")
    """Normalised innovation squared of the update."""
    warnings: list[str] = field(default_factory=list)
    """Recoveries the filter made during this step (e.g. covariance repaired)."""
    gated: bool = False
    """Rejected by the NIS gate (the measurement was valid but too far from the prediction)."""


@lru_cache(maxsize=64)
def gate_threshold(probability: float, dof: int) -> float:
    """Chi-square quantile of ``probability`` with ``dof`` degrees of freedom: the NIS gate, and the gate of
    every (track, detection) pair (tracker_filters.association)."""
    return float(chdtri(dof, 1.0 - probability))  # = scipy.stats.chi2.ppf, without importing scipy.stats


class Filter(ABC):
    """A recursive Bayesian estimator over one dynamics model.

    Attributes ``x`` (n,), ``P`` (n, n) and ``t`` (s) hold the current estimate once ``initialise`` ran.
    ``gate_probability`` (0 = off, set by the builder from the filter's ``gate_probability`` key) rejects a
    measurement whose NIS exceeds the chi-square quantile of that probability for its dimension: a gross
    outlier is gated and the estimate is left as it was before the measurement.
    """

    name: str = "filter"
    gate_probability: float = 0.0

    def __init__(self, dynamics: DynamicsModel) -> None:
        self.dynamics = dynamics
        self.x: np.ndarray | None = None
        self.P: np.ndarray | None = None
        self.t: float = float("nan")
        self._warnings: list[str] = []

    @property
    def labels(self) -> list[str]:
        return list(self.dynamics.labels)

    @property
    def initialised(self) -> bool:
        return self.x is not None

    def initialise(self, x0: np.ndarray, P0: np.ndarray, t0: float) -> None:
        """Start from mean x0 and covariance P0 at time t0."""
        self.x = np.array(x0, dtype=float)
        self.P = np.array(P0, dtype=float)
        self.t = float(t0)

    def diagnostics(self) -> dict[str, float]:
        """Extra per-step numbers published with the estimate (e.g. ``n_eff``)."""
        return {}

    def process(self, t: float, z: np.ndarray, R: np.ndarray, model: MeasurementModel) -> StepResult:
        """Predict to time t and update with measurement z (covariance R) through ``model``.

        Rejects, without touching the estimate, a measurement that is not finite or is older than the
        current estimate time. The time is converted to a Python float first: a numpy scalar time would
        turn every scalar operation of the predict (dt, RK4 in Python floats) into a slower numpy one.
        """
        if not self.initialised:
            raise RuntimeError(f"{self.name}: process() called before initialise()")
        t = float(t)
        z = np.asarray(z, dtype=float)
        R = np.asarray(R, dtype=float)
        if not (math.isfinite(t) and math.isfinite(z.sum()) and math.isfinite(R.sum())):  # one reduction each
            return StepResult(False, f"non-finite measurement at t={t}: z={z.tolist()}")
        if t < self.t:
            return StepResult(False, f"out-of-order measurement: t={t} s is before the estimate time {self.t} s")
        saved = (self.x.copy(), self.P.copy(), self.t)
        self._warnings = []
        try:
            self.predict(t)
            nis = self._update(z, R, model)
        except (np.linalg.LinAlgError, FloatingPointError, ValueError) as err:
            self.x, self.P, self.t = saved
            return StepResult(False, f"update failed and was undone ({err})", warnings=self._warnings)
        if self.gate_probability and nis > gate_threshold(self.gate_probability, z.shape[0]):
            self.x, self.P, self.t = saved
            return StepResult(
                False,
                f"gated outlier at t={t} s: NIS {nis:.4g} > "
                f"{gate_threshold(self.gate_probability, z.shape[0]):.4g} "
                f"(gate probability {self.gate_probability})",
                nis=nis,
                gated=True,
            )
        self.P = self._repaired(self.P, "after update")
        return StepResult(True, nis=nis, warnings=self._warnings)

    def predict(self, t: float) -> None:
        """Propagate the estimate to time t (no-op when t equals the current time)."""
        t = float(t)
        dt = t - self.t
        if dt != 0.0:
            self._predict(dt)
            self.P = self._repaired(self.P, "after predict")
        self.t = t

    def _repaired(self, P: np.ndarray, when: str) -> np.ndarray:
        P, repaired = ensure_pd(P)
        if repaired:
            self._warnings.append(f"{self.name}: covariance lost positive-definiteness {when}; repaired")
        return P

    @abstractmethod
    def _predict(self, dt: float) -> None:
        """Propagate ``x`` and ``P`` by dt seconds."""

    @abstractmethod
    def _update(self, z: np.ndarray, R: np.ndarray, model: MeasurementModel) -> float:
        """Update ``x`` and ``P`` with z; return the normalised innovation squared."""
