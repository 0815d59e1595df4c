"""Recursive star tracking after identification: the paper's SNA baseline and its JPDAF (Table 2).

Both follow identified stars (tracks keyed by catalogue index) from frame to frame on the image plane.

Star Neighbourhood Approach (SNA; Samaan, Mortari & Junkins 2005, the paper's baseline): each star's centroid
in the previous frame is carried to the current one with the known body rate (:func:`predict_centroids`), and
the measurement inside the Euclidean gate of radius 3√2·σ around the prediction is taken as the star's new
position, unfiltered. When two measurements fall inside, the nearer is taken; a measurement goes to at most one
star (the nearer one); a star with none is missed and coasts on its prediction.

JPDAF (paper Table 2): each star has a Kalman state [x ẋ y ẏ] under a motion model (motion.py); per frame

    1. X_r = F X_r (+ u_r),  P_r = F P_r Fᵀ + Q                                prediction (u_r: the known
                                                                                 image motion, rate-aided)
    2. ẑ_r = H X_r,  S_r = H P_r Hᵀ + R                                        (eqs. 6–7)
    3. gating d²_rj <= δ (eq. 5: tracker_filters.association.gaussian_hypotheses, every pair at once)
    4. β_rj from the feasible joint events, clustered (jpdaf.py, eqs. 8–12)
    5. ν_rj = z_j − ẑ_r,   ν_r = Σ_j β_rj ν_rj                                  combined innovation
    6. K_r = P_r Hᵀ S_r⁻¹,  X_r += K_r ν_r
    7. P_r = P_r − (Σ_j β_rj) K_r S_r K_rᵀ + K_r [Σ_j β_rj ν_rj ν_rjᵀ − ν_r ν_rᵀ] K_rᵀ   (spread of innovations)

Steps 2–7 run for all tracks at once on stacked arrays; the sums over j in 5 and 7 run over the pairs with
β_rj > 0 only, i.e. the detections in each star's gate (a few of the frame's ~70 stars).

The filtered positions H X_r are the star centroids handed to the attitude solver. With one target, no
clutter (λ = 0) and P_D = 1 the weights are one-hot and the JPDAF is a Kalman filter
(tests/test_star_tracking.py).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.special import chdtr

from star_tracker.attitude import rotation_matrix
from star_tracker.camera import Camera
from star_tracker.jpdaf import JointProbabilisticAssociator
from star_tracker.motion import MotionModel, image_turn, measurement_noise
from tracker_filters.association import gaussian_hypotheses
from tracker_filters.filter_base import gate_threshold

MISSED = -1


def member(values: np.ndarray, among: np.ndarray) -> np.ndarray:
    """np.isin for the few dozen catalogue indices of a frame's tracks: True where ``values`` (N,) is in
    ``among`` (M,), by one (N, M) comparison (a fraction of np.isin's cost at these sizes)."""
    return (np.asarray(values)[:, None] == np.asarray(among)[None, :]).any(axis=1)


def predict_centroids(camera: Camera, uv: np.ndarray, omega_body: np.ndarray, dt: float) -> np.ndarray:
    """Where the stars at pixels uv (N, 2) are seen dt later when the camera turns at the body rate
    ``omega_body`` (rad/s, camera frame): an inertial direction seen along b is seen along
    b' = exp(−[ω×] dt) b after the turn."""
    turn = rotation_matrix(-np.asarray(omega_body, dtype=float) * dt)
    return camera.project(camera.unproject(uv) @ turn.T)


def image_velocity(camera: Camera, uv: np.ndarray, omega_body: np.ndarray, dt: float = 1e-3) -> np.ndarray:
    """(N, 2) image velocity (px/s) of the stars at uv for the body rate ``omega_body`` (central difference)."""
    ahead = predict_centroids(camera, uv, omega_body, dt)
    behind = predict_centroids(camera, uv, omega_body, -dt)
    return (ahead - behind) / (2.0 * dt)


# ------------------------------------------------------------------------------------------------------ SNA


def sna_associate(predicted: np.ndarray, Z: np.ndarray, radius: float) -> np.ndarray:
    """(T,) index into Z of the measurement each predicted centroid (T, 2) takes inside its Euclidean gate of
    ``radius`` pixels (MISSED where none): the nearest, each measurement to the nearest star only."""
    predicted, Z = np.asarray(predicted, float).reshape(-1, 2), np.asarray(Z, float).reshape(-1, 2)
    T, N = len(predicted), len(Z)
    out = np.full(T, MISSED, dtype=np.int64)
    if T == 0 or N == 0:
        return out
    dx = predicted[:, None, 0] - Z[None, :, 0]
    dy = predicted[:, None, 1] - Z[None, :, 1]
    d = np.sqrt(dx * dx + dy * dy)
    d[~np.isfinite(d)] = np.inf
    near = np.argmin(d, axis=1)
    dn = d[np.arange(T), near]
    inside = np.flatnonzero(dn <= radius)
    order = inside[np.argsort(dn[inside], kind="stable")]  # nearest pair first
    j = near[order]
    rank = np.arange(len(order))
    first = np.full(N, len(order))
    np.minimum.at(first, j, rank)  # a measurement goes to the first that wants it
    won = first[j] == rank
    out[order[won]] = j[won]
    return out


@dataclass
class SNATracker:
    """The paper's baseline (module docstring)."""

    camera: Camera
    sigma_px: float
    max_misses: int = 3
    ids: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    uv: np.ndarray = field(default_factory=lambda: np.empty((0, 2)))
    misses: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))

    @property
    def radius(self) -> float:
        """The Euclidean gate 3√2·σ (pixels)."""
        return 3.0 * np.sqrt(2.0) * self.sigma_px

    def start(self, ids: np.ndarray, uv: np.ndarray) -> None:
        """Add stars (catalogue indices) at their identified centroids; a star already tracked is skipped."""
        ids, uv = np.asarray(ids, dtype=np.int64), np.asarray(uv, dtype=float).reshape(-1, 2)
        new = ~member(ids, self.ids)
        self.ids = np.concatenate([self.ids, ids[new]])
        self.uv = np.vstack([self.uv, uv[new]])
        self.misses = np.concatenate([self.misses, np.zeros(int(new.sum()), dtype=np.int64)])

    def step(self, Z: np.ndarray, dt: float, omega_body: np.ndarray) -> np.ndarray:
        """Associate one frame's centroids Z (N, 2): returns (T,) the index into Z taken by each track (MISSED
        where none); tracks missed more than ``max_misses`` times in a row, or predicted out of the image,
        are dropped after the call (the returned array refers to the tracks before dropping)."""
        predicted = predict_centroids(self.camera, self.uv, omega_body, dt) if len(self.ids) else self.uv
        taken = sna_associate(predicted, Z, self.radius)
        hit = taken >= 0
        Z = np.asarray(Z, float).reshape(-1, 2)
        self.uv = np.where(hit[:, None], Z[np.maximum(taken, 0)] if len(Z) else predicted, predicted)
        self.misses = np.where(hit, 0, self.misses + 1)
        self.drop((self.misses <= self.max_misses) & self.camera.in_image(self.uv))
        return taken

    def drop(self, keep: np.ndarray) -> None:
        """Keep only the tracks where ``keep`` is True."""
        self.ids, self.uv, self.misses = self.ids[keep], self.uv[keep], self.misses[keep]


# ---------------------------------------------------------------------------------------------------- JPDAF


@dataclass
class JPDAFStep:
    """One frame of the JPDAF."""

    detection: np.ndarray
    """(T,) most probable detection of each track (MISSED for a miss), tracks as before any drop."""
    weights: np.ndarray
    """(T, N + 1) β: [miss, detection 0 … N − 1] per track."""
    ids: np.ndarray
    """(T,) catalogue index of each track."""
    positions: np.ndarray
    """(T, 2) filtered centroids H X after the update (before any drop)."""
    position_sigma: np.ndarray
    """(T,) standard deviation per axis of each filtered centroid, √(tr(H P Hᵀ)/2) after the update."""


class JPDAFTracker:
    """JPDAF over the identified stars (module docstring)."""

    def __init__(
        self,
        motion: MotionModel,
        sigma_px: float,
        p_detect: float = 0.95,
        clutter_density: float | None = None,
        gate: float | None = None,
        max_events: int = 20000,
        max_misses: int = 3,
        camera: Camera | None = None,
    ) -> None:
        """``gate`` is the threshold δ on d² (default: the 99.9 % chi-square gate for 2-D, δ = 13.8);
        ``clutter_density`` per square pixel (None: the non-parametric form of jpdaf.py); ``camera``, when
        given, drops tracks predicted out of its image."""
        if sigma_px <= 0:
            raise ValueError(f"sigma_px must be > 0, got {sigma_px}")
        self.motion = motion
        self.sigma_px = float(sigma_px)
        self.R = measurement_noise(sigma_px)
        gate = gate_threshold(0.999, 2) if gate is None else float(gate)
        if gate <= 0:
            raise ValueError(f"gate must be > 0, got {gate}")
        self.gate = gate
        self.gate_probability = float(chdtr(2, gate))  # chi2.cdf(δ, 2)
        self.associator = JointProbabilisticAssociator(p_detect, clutter_density, max_events)
        self.max_misses = int(max_misses)
        self.camera = camera
        self.ids = np.empty(0, dtype=np.int64)
        self.x = np.empty((0, 4))
        self.P = np.empty((0, 4, 4))
        self.misses = np.empty(0, dtype=np.int64)

    def __len__(self) -> int:
        return len(self.ids)

    @property
    def positions(self) -> np.ndarray:
        """(T, 2) filtered centroids H X (a copy)."""
        return self.x[:, ::2].copy()

    def start(
        self, ids: np.ndarray, uv: np.ndarray, velocity: np.ndarray | None = None, velocity_sigma: float = 1.0
    ) -> None:
        """Start tracks for stars (catalogue indices) at centroids uv (N, 2), with image velocities (N, 2)
        (px/s, e.g. image_velocity from the body rate; zero if None) known to ``velocity_sigma`` px/s; the
        position variance is the measurement's σ². A star already tracked is skipped."""
        ids, uv = np.asarray(ids, dtype=np.int64), np.asarray(uv, dtype=float).reshape(-1, 2)
        vel = np.zeros_like(uv) if velocity is None else np.asarray(velocity, dtype=float).reshape(-1, 2)
        new = ~member(ids, self.ids)
        n = int(new.sum())
        x = np.column_stack([uv[new, 0], vel[new, 0], uv[new, 1], vel[new, 1]])
        P0 = np.diag([self.sigma_px**2, velocity_sigma**2, self.sigma_px**2, velocity_sigma**2])
        self.ids = np.concatenate([self.ids, ids[new]])
        self.x = np.vstack([self.x, x])
        self.P = np.concatenate([self.P, np.broadcast_to(P0, (n, 4, 4))])
        self.misses = np.concatenate([self.misses, np.zeros(n, dtype=np.int64)])

    def drop(self, keep: np.ndarray) -> None:
        """Keep only the tracks where ``keep`` is True."""
        self.ids, self.x, self.P, self.misses = self.ids[keep], self.x[keep], self.P[keep], self.misses[keep]

    def reseed(self, ids: np.ndarray, uv: np.ndarray, velocity_sigma: float = 1.0) -> None:
        """Restart the tracks of ``ids`` at the centroids uv (N, 2): position variance σ², velocity kept with
        variance ``velocity_sigma``² and no correlation (after a detected filter bias)."""
        rows = np.flatnonzero(member(self.ids, ids))
        where = {int(i): k for k, i in enumerate(np.asarray(ids))}
        uv = np.asarray(uv, dtype=float).reshape(-1, 2)
        for r in rows:
            self.x[r, [0, 2]] = uv[where[int(self.ids[r])]]
            self.P[r] = np.diag([self.sigma_px**2, velocity_sigma**2, self.sigma_px**2, velocity_sigma**2])

    def predict(self, dt: float, motion: MotionModel | None = None, displacement: np.ndarray | None = None) -> None:
        """Step 1 for every track (``motion`` replaces the tracker's model for this and later frames).
        ``displacement`` (T, 2), when given, is a known motion of each star over dt added to the predicted
        position as a control input — the rate-aided prediction: with the image motion the known body rate
        causes given this way (predict_centroids(p) − p), the velocity states hold only the motion the rate
        does not explain (zero for a perfect rate), and the filter averages the centroid noise over frames."""
        if motion is not None:
            self.motion = motion
        F, Q = self.motion.transition(dt)
        self.x = self.x @ F.T
        if displacement is not None and len(self.x):
            d = np.asarray(displacement, dtype=float).reshape(-1, 2)
            self.x[:, 0] += d[:, 0]
            self.x[:, 2] += d[:, 1]
        self.P = F @ self.P @ F.T + Q

    def turn_image(self, angle: float, centre: np.ndarray) -> None:
        """Turn every track by ``angle`` (rad, +x towards +y) about the image point ``centre``: positions
        about the centre, velocities and covariances with them (X ← T X + shift, P ← T P Tᵀ) — the paper's
        eq. 18 compensation of a measured rotation of the image (boresight jitter)."""
        T = image_turn(angle)
        centre = np.asarray(centre, dtype=float)
        self.x[:, [0, 2]] -= centre
        self.x = self.x @ T.T
        self.x[:, [0, 2]] += centre
        self.P = T @ self.P @ T.T

    def update(self, Z: np.ndarray) -> JPDAFStep:
        """Steps 2–7 with the frame's centroids Z (N, 2); then tracks missed more than ``max_misses`` times
        in a row (or out of the camera's image) are dropped."""
        Z = np.asarray(Z, dtype=float).reshape(-1, 2)
        T, N = len(self.ids), len(Z)
        ids = self.ids.copy()
        if T == 0:
            return JPDAFStep(np.empty(0, dtype=np.int64), np.empty((0, N + 1)), ids, np.empty((0, 2)), np.empty(0))
        Pzz = self.P[:, ::2, ::2]  # H P Hᵀ (T, 2, 2)
        zhat = self.x[:, ::2]  # H X (T, 2)
        S = Pzz + self.R
        nu_c, spread = np.zeros((T, 2)), np.zeros((T, 2, 2))
        if N == 0:
            beta = np.ones((T, 1))
        else:
            beta = self.associator.weights(gaussian_hypotheses(zhat, Pzz, Z, self.R, self.gate_probability))
            r, j = np.divmod(np.flatnonzero(beta), N + 1)
            r, j = r[j > 0], j[j > 0] - 1  # pairs with β_rj > 0
            nu = Z[j] - zhat[r]  # ν_rj
            b_nu = beta[r, j + 1][:, None] * nu
            for d in range(2):
                nu_c[:, d] = np.bincount(r, b_nu[:, d], minlength=T)  # ν_r = Σ_j β_rj ν_rj
                for e in range(d + 1):
                    spread[:, d, e] = spread[:, e, d] = np.bincount(r, b_nu[:, d] * nu[:, e], minlength=T)
            spread -= nu_c[:, :, None] * nu_c[:, None, :]
        detection = np.argmax(beta, axis=1) - 1  # column 0, the miss: MISSED
        K = self.P[:, :, ::2] @ np.linalg.inv(S)  # P Hᵀ S⁻¹ (T, 4, 2)
        detected = 1.0 - beta[:, 0]
        self.x = self.x + np.einsum("tij,tj->ti", K, nu_c)
        self.P = self.P + K @ (spread - detected[:, None, None] * S) @ K.transpose(0, 2, 1)  # step 7
        self.P = 0.5 * (self.P + self.P.transpose(0, 2, 1))
        self.misses = np.where(detection >= 0, 0, self.misses + 1)
        positions = self.positions
        position_sigma = np.sqrt(0.5 * (self.P[:, 0, 0] + self.P[:, 2, 2]))
        keep = self.misses <= self.max_misses
        if self.camera is not None:
            keep &= self.camera.in_image(positions)
        self.drop(keep)
        return JPDAFStep(detection, beta, ids, positions, position_sigma)

    def step(
        self, Z: np.ndarray, dt: float, motion: MotionModel | None = None, displacement: np.ndarray | None = None
    ) -> JPDAFStep:
        """predict(dt, motion, displacement) then update(Z)."""
        self.predict(dt, motion, displacement)
        return self.update(Z)
