"""The attitude bound across frames under the trackers' motion model: the PCRB of each star's centroid over the
frames it is seen in, then mapped to the frame's attitude.

Choice (stated): the bound is built on the centroids, as the trackers are (tracking.py: one independent
[x ẋ y ẏ] state per star), not on a 3-dof attitude state. Per star i, with the tracker's motion model (F, Q over
each frame interval: motion.py, the scenario's process noise σ_a), its measurement model z = H X + v,
v ~ N(0, σ² I) (H = motion.H) and its start covariance P_0 (the first detection's σ² in position, the tracker's
velocity prior), the information of the star's state obeys Tichavský et al.'s recursion
(tracker_filters.pcrb, eq. 1)

    J_{i,k+1} = (Q_k + F_k J_{i,k}⁻¹ F_kᵀ)⁻¹ + d_{i,k+1} Hᵀ H / σ²,      J_{i,0} = P_0⁻¹,               (1)

d_{i,k} = 1 when star i is detected in frame k (0 for a missed frame: no information added). The model is
linear-Gaussian, so J_{i,k}⁻¹ is the Kalman covariance of the star's centroid, the JPDAF's own P with one
target and no clutter (tracking.py). With P_{i,k} = [J_{i,k}⁻¹]_pos (2×2, px²) the centroid bound in tangent
units is ifov² P_{i,k}, and the stars being independent under the model, the frame's attitude information is
attitude_bound's J with each centroid's noise σ² I replaced by its bound:

    J_att,k = Σ_i H_iᵀ (ifov² P_{i,k})⁻¹ H_i,      H_i = ∂t_i/∂δθ (attitude_bound.centroid_jacobians),     (2)

over the stars detected in frame k, evaluated at their measured positions; J_att,k⁻¹ is the bound. With Q → ∞
(no carry-over between frames) it is the per-frame bound; with the trackers' Q it bounds any estimator of
centroids that follow the trackers' model. Two limits, stated: (a) the truth's stars do not follow that model:
the rate the trackers are given is exact, so the true residual motion is zero (Q_true = 0) and a tracker with
Q > 0 can do somewhat better on this truth than the model's bound (its reported P overstates its error);
(b) the stars move together (a rigid sky), which the per-star model ignores; a bound with that coupling and
Q = 0 would fall as 1/k without limit.

A star's frames are found without the catalogue, from the truth's attitudes: a centroid of frame k predicted
to frame j (b_j = A_j A_kᵀ b_k) is the same star as the centroid of frame j nearest to it inside ``radius``
(tracking.sna_associate: nearest first, one to one), for at most ``max_misses`` frames without a detection, as
the trackers carry a star. A false star starts a chain of its own (it adds information that does not exist;
the study's default has none).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from star_tracker.attitude_bound import centroid_jacobians
from star_tracker.motion import H as CENTROID
from star_tracker.tracking import sna_associate
from tracker_filters.pcrb import pcrb_recursion


def _carry(xy: np.ndarray, turn: np.ndarray) -> np.ndarray:
    """Tangent-plane positions xy (N, 2) of directions turned by ``turn`` (3, 3): b' = turn b."""
    b = np.column_stack([xy, np.ones(len(xy))]) @ turn.T
    return b[:, :2] / b[:, 2:]


def star_chains(
    frames: Sequence[np.ndarray], attitudes: np.ndarray, radius: float, max_misses: int
) -> list[np.ndarray]:
    """Per frame, the chain (star) index of each centroid: ``frames[k]`` (N_k, 2) tangent-plane centroids,
    ``attitudes`` (K, 3, 3) the true camera-from-ICRS attitudes, ``radius`` the association gate (tangent
    units), a chain ended after ``max_misses`` frames without a detection (module docstring)."""
    out: list[np.ndarray] = []
    last_frame = np.empty(0, dtype=np.int64)
    last_xy = np.empty((0, 2))
    for k, xy in enumerate(frames):
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        ids = np.full(len(xy), -1, dtype=np.int64)
        alive = np.flatnonzero(k - last_frame <= max_misses + 1)
        if len(alive) and len(xy):
            predicted = np.empty((len(alive), 2))
            for j in np.unique(last_frame[alive]):  # the chains last seen in frame j, carried to frame k
                rows = last_frame[alive] == j
                predicted[rows] = _carry(last_xy[alive[rows]], attitudes[k] @ attitudes[j].T)
            taken = sna_associate(predicted, xy, radius)
            hit = taken >= 0
            ids[taken[hit]] = alive[hit]
        new = np.flatnonzero(ids < 0)
        ids[new] = len(last_frame) + np.arange(len(new))
        last_frame = np.concatenate([last_frame, np.zeros(len(new), dtype=np.int64)])
        last_xy = np.vstack([last_xy, np.zeros((len(new), 2))])
        last_frame[ids], last_xy[ids] = k, xy
        out.append(ids)
    return out


def centroid_information(
    detected: np.ndarray, transitions: np.ndarray, noises: np.ndarray, J0: np.ndarray, scan: np.ndarray
) -> np.ndarray:
    """Eq. (1) for one star from its first detection: ``detected`` (K,) bool (detected[0] True),
    ``transitions``/``noises`` (K − 1, n, n) F and Q of each frame interval, ``J0`` the start information,
    ``scan`` a detection's information Hᵀ H / σ²; returns J (K, n, n) per frame (px units)."""
    if len(detected) == 1:
        return np.asarray(J0, dtype=float)[None]
    info = np.asarray(detected[1:], dtype=float)[:, None, None] * scan
    return pcrb_recursion(J0, transitions, noises, info)


def tracked_attitude_covariance(
    frames: Sequence[np.ndarray],
    chains: Sequence[np.ndarray],
    transitions: np.ndarray,
    noises: np.ndarray,
    P0: np.ndarray,
    sigma_px: float,
    ifov: float,
    measurement: np.ndarray = CENTROID,
) -> np.ndarray:
    """The bound J_att,k⁻¹ (K, 3, 3) (rad², camera frame) of eq. (2) per frame: ``frames`` and ``chains`` as
    star_chains', ``transitions``/``noises`` (K − 1, n, n) F and Q of each frame interval (px), ``P0`` (n, n)
    the start covariance, ``measurement`` (2, n) the H that picks the centroid from the state (the trackers'
    [x ẋ y ẏ] by default; np.eye(2) for a state of the centroid alone); NaN for a frame with fewer than two
    stars."""
    K = len(frames)
    J0 = np.linalg.inv(P0)
    scan = measurement.T @ measurement / sigma_px**2
    n_chains = 1 + max((int(c.max()) for c in chains if len(c)), default=-1)
    seen = np.zeros((n_chains, K), dtype=bool)
    at = np.zeros((n_chains, K, 2))  # each chain's centroid per frame where seen
    for k, c in enumerate(chains):
        seen[c, k] = True
        at[c, k] = frames[k]
    J_att = np.zeros((K, 3, 3))
    constant = bool(
        np.allclose(transitions, transitions[:1], rtol=1e-12, atol=0.0)
        and np.allclose(noises, noises[:1], rtol=1e-12, atol=0.0)
    )
    done: list[tuple[np.ndarray, np.ndarray]] = []  # (detections, J): reused for a chain with the same prefix
    for c in np.argsort(-seen.sum(axis=1), kind="stable"):
        frames_c = np.flatnonzero(seen[c])
        first, last = frames_c[0], frames_c[-1]
        mask = seen[c, first : last + 1]
        J = next(
            (
                Jd[: len(mask)]
                for d, Jd in done
                if constant and len(d) >= len(mask) and np.array_equal(d[: len(mask)], mask)
            ),
            None,
        )
        if J is None:
            J = centroid_information(mask, transitions[first:last], noises[first:last], J0, scan)
            done.append((mask, J))
        P_pos = measurement @ np.linalg.inv(J[frames_c - first]) @ measurement.T * ifov**2  # (n, 2, 2)
        Hi = centroid_jacobians(at[c, frames_c])
        J_att[frames_c] += np.swapaxes(Hi, 1, 2) @ np.linalg.solve(P_pos, Hi)
    P = np.full_like(J_att, np.nan)
    ok = np.array([np.sum(c >= 0) >= 2 for c in chains]) & (np.linalg.cond(J_att) < 1e15)
    P[ok] = np.linalg.inv(J_att[ok])
    return 0.5 * (P + np.swapaxes(P, 1, 2))
