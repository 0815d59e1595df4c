"""The star camera in the graph: the node kind ``star_camera`` (role sensor) for every entry of the scenario's
``star_cameras`` section; its core is star_tracker.star_camera. It subscribes the attitude truth (``/truth/state``, labels qw qx qy qz wx wy wz:
truth_model.py) and publishes, per frame,

- ``/NAME/measurement`` (bench_msgs/StarCentroids): the centroids (frames.simulate_frame: noise σ, P_D, false
  stars), brightest first, as tangent-plane coordinates with their magnitudes, σ, and the gyro's body rate
  over the interval since the previous frame (the paper's trackers take the rate as known; exact here) with
  its boresight jitter part;
- ``/NAME/star_truth`` (the same type, scoring only): per centroid, its star's noise-free position and
  catalogue (HIP) id, −1 for a false star. No estimator subscribes it.

    star_cameras:
      camera:
        fov_deg: 20.0            # full field across the width (camera.py)
        width: 1024
        height: 1024
        magnitude_limit: 6.0     # the on-board catalogue and the camera's detection limit
        epoch: 2025.0            # proper motion applied to this epoch (catalogue.py)
        merge_arcsec: 140.0      # pairs closer than this are one entry (unresolved by the camera)
        sigma_px: 0.2            # centroid noise, px per axis (1σ)
        p_detect: 0.95           # probability each star in view is detected
        false_stars: 2           # false stars per frame (fixed number) ...
        false_rate: 0.0          # ... plus a Poisson number with this mean
        mag_sigma: 0.1           # instrument magnitude noise
        cache_dir: null          # the catalogue cache (default: catalogue.default_cache_dir())
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench_engine.config import ScenarioError, Section
from bench_engine.scenario import scenario_seed
from bench_engine.graph import TRUTH_TOPIC, TRUTH_TYPE, NodeKind, NodeSpec, measurement_topic
from star_tracker.messages import STAR_CENTROIDS_TYPE, star_truth_topic

SECTION = "star_cameras"


@dataclass(frozen=True)
class CameraConfig:
    name: str
    fov_deg: float
    width: int
    height: int
    magnitude_limit: float
    epoch: float
    merge_arcsec: float
    sigma_px: float
    p_detect: float
    false_stars: int
    false_rate: float
    mag_sigma: float
    cache_dir: str | None


def read_cameras(cfg: dict) -> dict[str, CameraConfig]:
    """The ``star_cameras`` section, read strictly (registered section reader)."""
    sec = Section(cfg.get(SECTION), SECTION)
    out = {}
    for name in sec.keys():
        if not str(name).replace("_", "").isalnum():
            raise ScenarioError(f"star camera name '{name}' must be letters, digits and underscores")
        e = sec.section(name)
        out[name] = CameraConfig(
            name, e.get("fov_deg", float, 20.0, lambda v: 0.5 <= v <= 90.0, "in [0.5, 90] deg"),
            e.get("width", int, 1024, lambda v: 16 <= v <= 16384, "in [16, 16384] px"),
            e.get("height", int, 1024, lambda v: 16 <= v <= 16384, "in [16, 16384] px"),
            e.get("magnitude_limit", float, 6.0, lambda v: 2.0 <= v <= 9.0, "in [2, 9] (Hipparcos)"),
            e.get("epoch", float, 2025.0, lambda v: 1900.0 <= v <= 2100.0, "a year in [1900, 2100]"),
            e.get("merge_arcsec", float, 140.0, lambda v: 0.0 <= v <= 3600.0, "in [0, 3600] arcsec"),
            e.get("sigma_px", float, 0.2, lambda v: 0.0 < v <= 10.0, "in (0, 10] px"),
            e.get("p_detect", float, 0.95, lambda v: 0.0 < v <= 1.0, "in (0, 1]"),
            e.get("false_stars", int, 0, lambda v: 0 <= v <= 1000, "an integer in [0, 1000]"),
            e.get("false_rate", float, 0.0, lambda v: 0.0 <= v <= 1000.0, "in [0, 1000] per frame"),
            e.get("mag_sigma", float, 0.1, lambda v: 0.0 <= v <= 2.0, "in [0, 2] mag"),
            e.get("cache_dir", str, None))
        e.finish()
    sec.finish()
    return out


def camera_config(cfg: dict, name: str) -> CameraConfig:
    cameras = read_cameras(cfg)
    if name not in cameras:
        raise ScenarioError(f"unknown star camera '{name}'; the scenario's star_cameras: {sorted(cameras)}")
    return cameras[name]


def _spec(cfg: dict, name: str) -> NodeSpec:
    return NodeSpec(name, "star_camera", publishes={measurement_topic(name): STAR_CENTROIDS_TYPE,
                                                    star_truth_topic(name): STAR_CENTROIDS_TYPE},
                    subscribes={TRUTH_TOPIC: TRUTH_TYPE})


def _check(cfg: dict, name: str) -> None:
    camera_config(cfg, name)
    truth = (cfg.get("truth") or {}).get("model")
    if truth != "lvlh_camera":
        raise ScenarioError(f"star camera '{name}' needs the attitude truth 'truth.model: lvlh_camera', got {truth!r}")


def _star_camera(cfg: dict, name: str, run: dict | None = None):
    """The camera's core (star_tracker.star_camera.StarCameraStage), its random draws seeded by the run."""
    from star_tracker.star_camera import StarCameraStage  # catalogue, camera, frames: scipy, not for every node
    seed = int((run or {}).get("seed", scenario_seed(cfg)))
    rng = np.random.default_rng([seed, 3000 + sorted(read_cameras(cfg)).index(name)])
    return StarCameraStage(camera_config(cfg, name), rng, cfg.get("truth") or {})


STAR_CAMERA = NodeKind("star_camera", "sensor", "bench_engine.stage_node:StageNode",
                       instances=lambda cfg, requested: list(read_cameras(cfg)), spec=_spec, check=_check,
                       stage=_star_camera)
