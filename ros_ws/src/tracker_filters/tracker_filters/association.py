"""Data association: which detection of a step (if any) updates each track's filter.

Split as in Stone Soup: a **hypothesiser** scores every (track, detection) pair and gates it; a **data
associator** picks from those hypotheses. For track i with predicted measurement zhat_i and its covariance
Pzz_i (without noise), and detection z_j with noise covariance R_j (Bar-Shalom, Willett & Tian, "Tracking and
Data Fusion", 2011, ch. 2-3):

    nu_ij = z_j - zhat_i  (angles wrapped by the model's residual)
    S_ij  = Pzz_i + R_j                                   innovation covariance
    d2_ij = nu_ij' S_ij^-1 nu_ij                          squared Mahalanobis distance
    log g_ij = -1/2 (d2_ij + log det(2 pi S_ij))          measurement likelihood
    gated_ij  <=>  d2_ij <= gamma = chi2.ppf(P_G, dim z)   (the gate holds the target with probability P_G)

The predicted measurement comes from the track's filter (:func:`measurement_prediction`): the filter's own
``predict_measurement(model, t)`` when it has one, the weighted particle moments for a particle cloud, and
otherwise the first-order (EKF) moments zhat = h(x), Pzz = H P H'.

Every associator returns, per track, an :class:`Association`: the chosen detection (``NO_DETECTION`` on a
miss) and the weights of all its hypotheses, [missed, detection 0, ..., detection N-1]. Global nearest
neighbour (:class:`GlobalNearestNeighbour`) gives one-hot weights. A probabilistic associator (PDA, JPDA:
beta_i0 for the miss and beta_ij over the gated detections, from ``log_likelihood``, P_D, P_G and the clutter
density) is a new class with the same ``associate`` returning soft weights; the tracker then needs a
probabilistic update for those tracks (tracker_filters.tracker.Tracker.update_track).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from scipy.optimize import linear_sum_assignment

from tracker_filters.filter_base import gate_threshold

NO_DETECTION = -1


@dataclass
class MeasurementPrediction:
    """What a track expects to measure: zhat (d,) and its covariance Pzz (d, d), measurement noise excluded."""

    z: np.ndarray
    Pzz: np.ndarray


def linearised_prediction(x: np.ndarray, P: np.ndarray, model, t: float) -> MeasurementPrediction:
    """First-order moments: zhat = h(x), Pzz = H P H' with H = dh/dx at x."""
    H = model.jacobian(x, t)
    return MeasurementPrediction(np.asarray(model.h(x, t), dtype=float), H @ P @ H.T)


def measurement_prediction(flt, model, t: float) -> MeasurementPrediction:
    """The predicted measurement of a filter already predicted to time t (its state is only read)."""
    own = getattr(flt, "predict_measurement", None)
    if callable(own):
        return own(model, t)
    particles = getattr(flt, "particles", None)
    if particles is not None:
        w = np.asarray(flt.weights, dtype=float)
        Y = model.h(particles, t)  # (M, d)
        ref = model.h(flt.x, t)
        zhat = ref + w @ model.residual(Y, ref)  # weighted mean, angles averaged as residuals
        r = model.residual(Y, zhat)
        return MeasurementPrediction(zhat, (r * w[:, None]).T @ r)  # Pzz = sum_m w_m r_m r_m'
    return linearised_prediction(flt.x, flt.P, model, t)


@dataclass
class Hypotheses:
    """Every (track, detection) pair of one step, T tracks by N detections."""

    z_pred: np.ndarray
    """(T, d) predicted measurement of each track."""
    nu: np.ndarray
    """(T, N, d) innovations z_j - zhat_i."""
    S: np.ndarray
    """(T, N, d, d) innovation covariances Pzz_i + R_j."""
    d2: np.ndarray
    """(T, N) squared Mahalanobis distances (inf for a pair that cannot be scored; see ``gated``)."""
    log_likelihood: np.ndarray
    """(T, N) log N(nu_ij; 0, S_ij)."""
    gate: float
    """Gate threshold gamma on d2 (np.inf when there is no detection to gate)."""
    gate_probability: float

    @property
    def gated(self) -> np.ndarray:
        """(T, N) True where detection j is inside track i's gate."""
        return self.d2 <= self.gate

    @property
    def n_tracks(self) -> int:
        return self.d2.shape[0]

    @property
    def n_detections(self) -> int:
        return self.d2.shape[1]


def gaussian_hypotheses(
    z_pred: np.ndarray,
    Pzz: np.ndarray,
    Z: np.ndarray,
    R: np.ndarray,
    gate_probability: float,
    residual: Callable | None = None,
) -> Hypotheses:
    """The module docstring's quantities for T tracks' predictions z_pred (T, d), Pzz (T, d, d) against the
    detections Z (N, d), computed for every pair at once: R is one noise covariance (d, d) shared by the
    detections (one innovation covariance per track) or one per detection (N, d, d). ``residual(z, z_pred)``
    (broadcasting) gives nu (default: the plain difference). With the Cholesky factor S = L L' and
    L e = nu, d2 = |e|^2 and log det S = 2 sum log L_ii; e is solved component by component over the few
    dimensions d, each step a vector operation over all pairs. A pair whose d2 is not finite (a
    prediction or detection that is not a number) is outside every gate: d2 = inf, log-likelihood -inf."""
    z_pred, Z = np.asarray(z_pred, dtype=float), np.asarray(Z, dtype=float)
    T, (N, d) = len(z_pred), Z.shape
    nu = np.empty((d, T, N))  # by component: each a contiguous (T, N) array
    if residual is None:
        for i in range(d):
            np.subtract(Z[None, :, i], z_pred[:, None, i], out=nu[i])
    else:
        nu[...] = np.moveaxis(np.asarray(residual(Z[None, :, :], z_pred[:, None, :]), dtype=float), -1, 0)
    S = np.asarray(Pzz, dtype=float).reshape(T, 1, d, d) + np.asarray(R, dtype=float)  # (T, 1 or N, d, d)
    L = np.linalg.cholesky(S)
    e = np.empty((d, T, N))  # L e = nu by forward substitution, each step over all pairs
    for i in range(d):
        acc = nu[i]
        for j in range(i):
            acc = acc - L[..., i, j] * e[j]
        np.divide(acc, L[..., i, i], out=e[i])
    d2 = np.einsum("ktn,ktn->tn", e, e)
    log_det = 2.0 * np.log(np.diagonal(L, axis1=-2, axis2=-1)).sum(axis=-1)  # (T, 1 or N)
    loglik = -0.5 * (d2 + (log_det + d * np.log(2.0 * np.pi)))
    bad = ~np.isfinite(loglik)
    if bad.any():
        d2[bad], loglik[bad] = np.inf, -np.inf
    gate = gate_threshold(float(gate_probability), d) if N else np.inf
    S = np.broadcast_to(S, (T, N, d, d))
    return Hypotheses(z_pred.copy(), nu.transpose(1, 2, 0), S, d2, loglik, gate, float(gate_probability))


class MahalanobisHypothesiser:
    """Scores every (track, detection) pair by its squared Mahalanobis distance and gates it with the
    chi-square gate of probability ``gate_probability`` (module docstring; :func:`gaussian_hypotheses`)."""

    def __init__(self, gate_probability: float = 0.999) -> None:
        if not 0.0 < gate_probability < 1.0:
            raise ValueError(f"gate_probability must be in (0, 1), got {gate_probability}")
        self.gate_probability = float(gate_probability)

    def hypothesise(
        self, predictions: Sequence[MeasurementPrediction], Z: np.ndarray, R: np.ndarray, model
    ) -> Hypotheses:
        """Hypotheses of the detections Z (N, d), R (N, d, d) against each track's prediction. A detection
        with a NaN/inf value or covariance is outside every gate (d2 = inf)."""
        Z = np.asarray(Z, dtype=float)
        R = np.asarray(R, dtype=float)
        T, (_, d) = len(predictions), Z.shape
        valid = np.isfinite(Z).all(axis=1) & np.isfinite(R).all(axis=(1, 2))
        if not valid.all():  # score stand-ins, then put the invalid ones out of reach
            hyp = self.hypothesise(
                predictions, np.where(valid[:, None], Z, 0.0), np.where(valid[:, None, None], R, np.eye(d)), model
            )
            hyp.d2[:, ~valid], hyp.log_likelihood[:, ~valid] = np.inf, -np.inf
            hyp.nu[:, ~valid] = np.nan
            hyp.S = hyp.S.copy()
            hyp.S[:, ~valid] = np.nan
            return hyp
        z_pred = np.array([p.z for p in predictions], dtype=float).reshape(T, d)
        Pzz = np.array([p.Pzz for p in predictions], dtype=float).reshape(T, d, d)
        return gaussian_hypotheses(z_pred, Pzz, Z, R, self.gate_probability, model.residual)


def hypothesise(
    states: Sequence[np.ndarray],
    covariances: Sequence[np.ndarray],
    Z: np.ndarray,
    R: np.ndarray,
    model,
    t: float,
    gate_probability: float,
) -> Hypotheses:
    """Hypotheses of Z against tracks given by their predicted states and covariances (first-order
    measurement prediction)."""
    predictions = [
        linearised_prediction(np.asarray(x, float), np.asarray(P, float), model, t) for x, P in zip(states, covariances)
    ]
    return MahalanobisHypothesiser(gate_probability).hypothesise(predictions, Z, R, model)


@dataclass
class Association:
    """One track's share of a step's association."""

    detection: int
    """The detection that updates the track (its most probable hypothesis), NO_DETECTION on a miss."""
    weights: np.ndarray
    """(N + 1,) probability of each hypothesis: [missed, detection 0, ..., detection N-1]; sums to 1."""

    @property
    def is_hard(self) -> bool:
        """True when one hypothesis carries all the weight (a plain filter update, or none, follows)."""
        return bool(self.weights[self.detection + 1] == 1.0)

    @staticmethod
    def hard(detection: int, n_detections: int) -> Association:
        weights = np.zeros(n_detections + 1)
        weights[detection + 1] = 1.0
        return Association(int(detection), weights)


class DataAssociator(Protocol):
    def associate(self, hypotheses: Hypotheses) -> list[Association]:
        """One Association per track, in the tracks' order."""


class GlobalNearestNeighbour:
    """The joint assignment of gated (track, detection) pairs, each detection to at most one track, that
    assigns as many tracks as possible and, among those, has the least total d2 (Hungarian algorithm,
    scipy.optimize.linear_sum_assignment). A track with no gated detection left is missed."""

    def associate(self, hypotheses: Hypotheses) -> list[Association]:
        T, N = hypotheses.n_tracks, hypotheses.n_detections
        chosen = [NO_DETECTION] * T
        gated = hypotheses.gated
        if gated.any():
            d2 = hypotheses.d2
            # a pair outside the gate costs more than any set of gated pairs: more tracks assigned always wins
            forbidden = 1.0 + T * float(np.max(d2[gated]))
            rows, cols = linear_sum_assignment(np.where(gated, d2, forbidden))
            for i, j in zip(rows, cols):
                if gated[i, j]:
                    chosen[i] = int(j)
        return [Association.hard(j, N) for j in chosen]
