"""Data association: which detection of a step (if any) each track's filter is updated with.

Split as in Stone Soup: a hypothesiser scores every (track, detection) pair and gates it; a data associator
picks a joint assignment from those hypotheses. For track i with predicted state x_i, covariance P_i and a
detection z_j with covariance R_j through measurement model h (Bar-Shalom, Willett & Tian, "Tracking and
Data Fusion", 2011, ch. 2-3):

    nu_ij = z_j - h(x_i)  (angles wrapped),  S_ij = H_i P_i H_i' + R_j,  d2_ij = nu_ij' S_ij^-1 nu_ij

and the pair is in the gate when d2_ij <= gamma = chi2.ppf(P_G, dim z). Global nearest neighbour (GNN) takes
the assignment of gated pairs with the least total d2 (Hungarian algorithm, scipy's linear_sum_assignment),
each detection used at most once; a track with no gated detection is missed. A probabilistic associator
(PDA/JPDA: weights beta_ij over the gated hypotheses) implements the same ``associate`` on the same
hypotheses.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.stats import chi2

NO_DETECTION = -1


@dataclass
class Hypotheses:
    """Every (track, detection) pair of one step: d2 (T, N) with np.inf outside the gate."""

    d2: np.ndarray
    gate: float

    @property
    def gated(self) -> np.ndarray:
        return np.isfinite(self.d2)


def hypothesise(states: Sequence[np.ndarray], covariances: Sequence[np.ndarray], Z: np.ndarray, R: np.ndarray,
                model, t: float, gate_probability: float) -> Hypotheses:
    """Mahalanobis distances d2 (T, N) of every detection Z (N, d), R (N, d, d) to every predicted track, inf
    outside the chi-square gate of probability ``gate_probability``."""
    Z = np.asarray(Z, dtype=float)
    d2 = np.full((len(states), len(Z)), np.inf)
    if len(Z) == 0:
        return Hypotheses(d2, np.inf)
    gate = float(chi2.ppf(gate_probability, Z.shape[1]))
    for i, (x, P) in enumerate(zip(states, covariances)):
        H = model.jacobian(x, t)
        HPH = H @ P @ H.T
        nu = model.residual(Z, model.h(x, t))
        for j in range(len(Z)):
            value = float(nu[j] @ np.linalg.solve(HPH + R[j], nu[j]))
            if value <= gate:
                d2[i, j] = value
    return Hypotheses(d2, gate)


class DataAssociator(Protocol):
    def associate(self, hypotheses: Hypotheses) -> list[int]:
        """The detection index of each track, NO_DETECTION for a missed track."""


class GlobalNearestNeighbour:
    """The joint assignment of gated (track, detection) pairs with the least total d2."""

    def associate(self, hypotheses: Hypotheses) -> list[int]:
        d2 = hypotheses.d2
        chosen = [NO_DETECTION] * d2.shape[0]
        if d2.size == 0 or not np.any(np.isfinite(d2)):
            return chosen
        big = 1e6 * (1.0 + np.max(d2[np.isfinite(d2)]))  # a gated pair always beats leaving a track missed
        rows, cols = linear_sum_assignment(np.where(np.isfinite(d2), d2, big))
        for i, j in zip(rows, cols):
            if np.isfinite(d2[i, j]):
                chosen[i] = int(j)
        return chosen
