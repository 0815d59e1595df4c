"""The star_tracker study's bound (registered in tracking_bench.bounds as ``wahba``): per frame, the attitude CRB
of a star camera's recorded centroids (star_tracker.attitude_bound), for bench_eval.bounds' scoring.

    scoring:
      bounds:
        wahba: {bound: wahba, params: {camera: camera}, from_s: 1.0}
"""
from __future__ import annotations

import numpy as np

from bench_engine.config import Section
from bench_eval.bounds import Bound, BoundSeries
from bench_eval.scoring import BagData


def _wahba_check(cfg: dict, params: dict) -> None:
    from star_tracker.camera_stage import camera_config
    sec = Section(params, "scoring.bounds.params")
    camera_config(cfg, sec.get("camera", str))
    sec.finish()


def _wahba_run(data: BagData, params: dict) -> BoundSeries:
    """Per frame of star camera ``camera``, the inverse Fisher information of the attitude error (rx ry rz,
    camera frame) from the frame's recorded centroids and the camera's centroid noise (sigma_px over the focal
    length); NaN for a frame with fewer than two stars. A bound per frame, without the trackers' motion model."""
    from star_tracker.attitude_bound import attitude_information
    from star_tracker.camera_stage import camera_config
    from tracker_filters.pcrb import information_to_covariance
    conf = camera_config(data.scenario, params["camera"])
    sigma = conf.sigma_px * conf.camera().ifov
    frames = data.measurements.get(params["camera"], {})
    steps = np.array(sorted(frames), dtype=np.int64)
    J = np.array([attitude_information(frames[int(k)], sigma) for k in steps]).reshape(-1, 3, 3)
    return BoundSeries(steps, np.array([data.truth[int(k)][0] for k in steps]), ["rx", "ry", "rz"],
                       information_to_covariance(J))


WAHBA = Bound(run=_wahba_run, check=_wahba_check)
