"""The star_tracker study's bounds (registered in tracking_bench.bounds), for bench_eval.bounds' scoring:

- ``wahba``: per frame, the attitude CRB of a star camera's recorded centroids (star_tracker.attitude_bound);
- ``wahba_tracked``: across frames, the attitude bound under a star tracker's motion model: each star's
  centroid PCRB with the tracker's process noise, mapped to the attitude (star_tracker.tracked_bound).

    scoring:
      bounds:
        wahba: {bound: wahba, params: {camera: camera}, from_s: 1.0}
        wahba_tracked: {bound: wahba_tracked, params: {tracker: jpdaf_wahba}, from_s: 1.0}
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench_engine.config import ScenarioError
from bench_engine.labels import ANGULAR_RATE, QUATERNION, ROTATION
from bench_engine.settings import Settings, setting
from bench_eval.bounds import Bound, BoundSeries
from bench_eval.scoring import BagData
from orbit_sim.truth import read_truth
from star_tracker.attitude import matrix_from_quaternion
from star_tracker.attitude_bound import attitude_information
from star_tracker.camera_stage import camera_config
from star_tracker.motion import H as CENTROID
from star_tracker.motion import image_turn
from star_tracker.pipeline import jpdaf_motion
from star_tracker.star_camera import camera_of, lvlh_boresight_rate
from star_tracker.tracked_bound import star_chains, tracked_attitude_covariance
from star_tracker.tracker_stage import tracker_config
from tracker_filters.pcrb import information_to_covariance


@dataclass(frozen=True, kw_only=True)
class WahbaParameters(Settings):
    """The wahba bound's ``params``."""

    camera: str = setting(doc="the star camera (an entry of star_cameras) whose recorded centroids it bounds")


def _wahba_check(cfg: dict, params: WahbaParameters) -> None:
    camera_config(cfg, params.camera)


def _wahba_run(data: BagData, params: WahbaParameters) -> BoundSeries:
    """Per frame of star camera ``camera``, the inverse Fisher information of the attitude error (rx ry rz,
    camera frame) from the frame's recorded centroids and the camera's centroid noise (sigma_px over the focal
    length); NaN for a frame with fewer than two stars. A bound per frame, without the trackers' motion model."""
    conf = camera_config(data.scenario, params.camera)
    sigma = conf.sigma_px * camera_of(conf).ifov
    frames = data.measurements.get(params.camera, {})
    steps = np.array(sorted(frames), dtype=np.int64)
    J = np.array([attitude_information(frames[int(k)], sigma) for k in steps]).reshape(-1, 3, 3)
    return BoundSeries(
        steps, np.array([data.truth[int(k)][0] for k in steps]), list(ROTATION), information_to_covariance(J)
    )


WAHBA = Bound(run=_wahba_run, check=_wahba_check, params=WahbaParameters)


@dataclass(frozen=True, kw_only=True)
class TrackedParameters(Settings):
    """The wahba_tracked bound's ``params``."""

    tracker: str = setting(doc="a JPDAF star tracker of the scenario (an entry of star_trackers)")
    dynamics: str = setting(
        "tracker",
        choices=("tracker", "truth"),
        doc="tracker: the bound under the tracker's motion model, its σ_a and velocity prior; "
        "truth: the truth's (the rate is exact: a lower bound for any estimator)",
    )


def _tracked_settings(cfg: dict, params: TrackedParameters):
    """(tracker config, camera config, dynamics) of the params: ``tracker``, a JPDAF star tracker of the
    scenario (its motion model, aid and σ_a: _tracker_model); ``dynamics``: ``tracker`` (default: the bound
    under the trackers' model, its σ_a and velocity prior) or ``truth`` (the truth's: the rate is exact, so a star's
    centroid is its first position
    carried by the known turn, no residual velocity, Q = 0: the information of n detections is n/σ², a lower
    bound for any estimator on this truth)."""
    conf = tracker_config(cfg, params.tracker)
    if conf.tracker != "jpdaf":
        raise ScenarioError(
            f"'{params.where('tracker')}': '{params.tracker}' must be a JPDAF (tracker: jpdaf), got {conf.tracker}"
        )
    return conf, camera_config(cfg, conf.camera), params.dynamics


def _tracked_check(cfg: dict, params: TrackedParameters) -> None:
    _tracked_settings(cfg, params)


def _tracker_model(
    conf, sigma_px: float, dts: np.ndarray, rates: np.ndarray, mount_rate: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(F, Q) of each frame interval (K − 1, 4, 4) and the start covariance P_0 of a JPDAF star tracker
    (pipeline.JPDAFTracking), with the truth's body rate ``rates`` (K − 1, 3) over each interval (what its gyro
    gives it) and the LVLH mount's boresight rate: ``aid: rate``, constant velocity with its σ_a on what the rate
    does not explain, P_0 = σ² (px, px/s) for both; otherwise the motion model of pipeline.motion_for on the
    image velocities (P_0: σ² px², 1 (px/s)²), and with ``aid: jitter`` the turn of the image by −j Δt before
    each prediction (eq. 18, JPDAFTracker.turn_image: F ← F T, an offset of the positions adding no
    information)."""
    F, Q = np.zeros((len(dts), 4, 4)), np.zeros((len(dts), 4, 4))
    for i, (dt, w) in enumerate(zip(dts, rates)):
        jitter = float(w[2]) - mount_rate if conf.aid == "jitter" else 0.0
        F[i], Q[i] = jpdaf_motion(conf.motion, conf.aid, conf.sigma_a, float(w[2]), jitter).transition(float(dt))
        if conf.aid == "jitter":
            F[i] = F[i] @ image_turn(-jitter * dt)
    velocity = sigma_px**2 if conf.aid == "rate" else 1.0
    return F, Q, np.diag([sigma_px**2, velocity, sigma_px**2, velocity])


def _tracked_run(data: BagData, params: TrackedParameters) -> BoundSeries:
    """Per frame of the tracker's camera, the attitude bound (rx ry rz, camera frame) of
    star_tracker.tracked_bound: the stars' frames chained with the truth's attitudes, each star's centroid PCRB
    under the tracker's model (_tracker_model; R = σ² with the tracker's σ), mapped to the attitude; ``dynamics: truth``
    takes the truth's (a centroid state alone, F = I, Q = 0, P_0 = σ² I: _tracked_settings)."""
    conf, cam, dynamics = _tracked_settings(data.scenario, params)
    sigma_px = conf.sigma_px if conf.sigma_px is not None else cam.sigma_px
    ifov = camera_of(cam).ifov
    frames_by_step = data.measurements.get(conf.camera, {})
    steps = np.array(sorted(frames_by_step), dtype=np.int64)
    t = np.array([data.truth[int(k)][0] for k in steps])
    q = [data.truth_labels.index(lab) for lab in QUATERNION]
    attitudes = np.array([matrix_from_quaternion(data.truth[int(k)][1][q]) for k in steps]).reshape(-1, 3, 3)
    frames = [np.asarray(frames_by_step[int(k)], dtype=float).reshape(-1, 2) for k in steps]
    chains = star_chains(frames, attitudes, 6.0 * np.sqrt(2.0) * sigma_px * ifov, conf.max_misses)
    if dynamics == "tracker":
        w = [data.truth_labels.index(lab) for lab in ANGULAR_RATE]
        rates = np.array([data.truth[int(k)][1][w] for k in steps[:-1]]).reshape(-1, 3)
        F, Q, P0 = _tracker_model(conf, sigma_px, np.diff(t), rates, lvlh_boresight_rate(read_truth(data.scenario)))
        H = CENTROID
    else:
        F, Q = np.broadcast_to(np.eye(2), (max(len(t) - 1, 0), 2, 2)), np.zeros((max(len(t) - 1, 0), 2, 2))
        P0, H = sigma_px**2 * np.eye(2), np.eye(2)
    P = tracked_attitude_covariance(frames, chains, F, Q, P0, sigma_px, ifov, H) if len(steps) else np.zeros((0, 3, 3))
    return BoundSeries(steps, t, list(ROTATION), P)


WAHBA_TRACKED = Bound(run=_tracked_run, check=_tracked_check, params=TrackedParameters)
