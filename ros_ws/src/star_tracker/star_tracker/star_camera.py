"""The star camera's core (the node kind ``star_camera``: camera_stage.py): per attitude truth sample, the frame's
measured centroids and their truth (frames.simulate_frame), with the gyro's body rate and its jitter part; and
what a camera's settings (camera_stage.CameraConfig) make: its pinhole model, its on-board catalogue and the
k-vector of the catalogue's pairs.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from bench_engine.graph import measurement_topic
from bench_engine.labels import ANGULAR_RATE, QUATERNION
from bench_engine.stage import Outputs, TruthSample, python_log
from orbit_sim.truth import TruthSection
from star_tracker.attitude import matrix_from_quaternion
from star_tracker.camera import Camera
from star_tracker.catalogue import StarCatalogue, load_catalogue
from star_tracker.frames import FALSE_STAR, simulate_frame
from star_tracker.kvector import PairTable
from star_tracker.messages import StarFrame, star_truth_topic
from star_tracker.truth_model import orbit_of


def camera_of(conf) -> Camera:
    """The pinhole camera of a camera's settings (camera_stage.CameraConfig)."""
    return Camera(conf.fov_deg, conf.width, conf.height)


def catalogue_of(conf) -> StarCatalogue:
    """The on-board catalogue of a camera's settings (catalogue.load_catalogue: cached on disk, rebuilt when
    missing or corrupt; built once per process for the same settings)."""
    return _catalogue(conf.magnitude_limit, conf.epoch, conf.merge_arcsec, conf.cache_dir)


@lru_cache(maxsize=2)
def _catalogue(magnitude_limit: float, epoch: float, merge_arcsec: float, cache_dir: str | None) -> StarCatalogue:
    return load_catalogue(magnitude_limit, epoch, merge_arcsec, cache_dir=cache_dir)


def pair_table(conf) -> PairTable:
    """The k-vector of the pairs of a camera's catalogue (camera_stage.CameraConfig), built once per process and
    shared (it is read-only) by the trackers of every camera with that catalogue and field, whatever its noise:
    the cells of a sweep over sigma_px, forked from one process (bench_engine.preload), share one."""
    c = conf
    return _pair_table(c.magnitude_limit, c.epoch, c.merge_arcsec, c.cache_dir, c.fov_deg, c.width, c.height)


@lru_cache(maxsize=4)
def _pair_table(
    magnitude_limit: float, epoch: float, merge_arcsec: float, cache_dir: str | None, fov: float, w: int, h: int
) -> PairTable:
    catalogue = _catalogue(magnitude_limit, epoch, merge_arcsec, cache_dir)
    return PairTable(catalogue, Camera(fov, w, h).max_separation)


def lvlh_boresight_rate(truth: TruthSection) -> float:
    """The boresight component of the LVLH mount's own rate (rad/s) for the scenario's ``truth`` section
    (orbit_sim.truth.read_truth): n for an orbit-normal boresight, 0 for the zenith one (sky_motion.py); the rest
    of ω_z is jitter."""
    if truth.model != "lvlh_camera" or truth.options.boresight != "normal":
        return 0.0
    return orbit_of(truth.options).mean_motion


class StarCameraStage:
    """Simulated star camera ``name`` (camera_stage.py's docstring) of the settings ``conf``, drawing from ``rng``,
    on the scenario's ``truth`` section (orbit_sim.truth.read_truth)."""

    def __init__(self, name: str, conf, rng: np.random.Generator, truth: TruthSection) -> None:
        self.conf, self.name = conf, name
        self.camera, self.catalogue = camera_of(conf), catalogue_of(conf)
        self.rng = rng
        self.mount_rate = lvlh_boresight_rate(truth)
        self.topic, self.truth_topic = measurement_topic(name), star_truth_topic(name)
        self.sigma = self.conf.sigma_px * self.camera.ifov
        self.previous_rate: np.ndarray | None = None
        self.log = python_log(name)

    def on_input(self, topic: str, truth: TruthSample) -> Outputs:
        labels = list(truth.labels)
        if not all(lab in labels for lab in (*QUATERNION, *ANGULAR_RATE)):
            raise ValueError(
                f"star camera '{self.name}' needs a truth labelled {[*QUATERNION, *ANGULAR_RATE]}, got {labels}"
            )
        q = truth.state[[labels.index(lab) for lab in QUATERNION]]
        rate = truth.state[[labels.index(lab) for lab in ANGULAR_RATE]]
        A = matrix_from_quaternion(q)
        c = self.conf
        frame = simulate_frame(
            self.catalogue,
            self.camera,
            A,
            self.rng,
            sigma_px=c.sigma_px,
            p_detect=c.p_detect,
            n_false=c.false_stars,
            false_rate=c.false_rate,
            mag_sigma=c.mag_sigma,
        )
        gyro = rate if self.previous_rate is None else self.previous_rate  # the interval since the last frame
        self.previous_rate = rate
        star = frame.truth != FALSE_STAR
        true_uv = frame.uv.copy()
        true_uv[star] = self.camera.project(self.catalogue.vectors[frame.truth[star]] @ A.T)
        ids = np.where(star, self.catalogue.ids[np.maximum(frame.truth, 0)], -1)
        common = dict(step=truth.step, t_ns=truth.t_ns, frame_id=self.name, source=self.name)
        measured = StarFrame(
            **common,
            xy=self.camera.to_tangent(frame.uv),
            magnitudes=frame.magnitudes,
            sigma=self.sigma,
            body_rate=gyro,
            jitter_rate=float(gyro[2]) - self.mount_rate,
        )
        truth_frame = StarFrame(
            **common,
            xy=self.camera.to_tangent(true_uv),
            magnitudes=frame.magnitudes,
            sigma=0.0,
            body_rate=gyro,
            jitter_rate=float(gyro[2]) - self.mount_rate,
            star_id=ids,
        )
        return [(self.topic, measured), (self.truth_topic, truth_frame)]
