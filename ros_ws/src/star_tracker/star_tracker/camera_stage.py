"""The star camera in the graph: the node kind ``star_camera`` (role sensor) for every entry of the scenario's
``star_cameras`` section; its core is star_tracker.star_camera. It subscribes the attitude truth (``/truth/state``,
labels qw qx qy qz wx wy wz:
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

from bench_engine.config import ScenarioError
from bench_engine.graph import TRUTH_TOPIC, TRUTH_TYPE, NodeKind, NodeSpec, measurement_topic
from bench_engine.scenario import scenario_seed
from bench_engine.settings import Check, SectionReader, Settings, between, read_entries, setting
from orbit_sim.truth import read_truth
from star_tracker.messages import STAR_CENTROIDS_TYPE, star_truth_topic

SECTION = "star_cameras"


@dataclass(frozen=True, kw_only=True)
class CameraConfig(Settings):
    """One entry of ``star_cameras`` (the module docstring)."""

    fov_deg: float = setting(20.0, unit="deg", check=between(0.5, 90.0, "deg"), doc="full field across the width")
    width: int = setting(1024, check=between(16, 16384, "px", what="an integer in"), doc="image width [px]")
    height: int = setting(1024, check=between(16, 16384, "px", what="an integer in"), doc="image height [px]")
    magnitude_limit: float = setting(
        6.0,
        check=between(2.0, 9.0, "(Hipparcos)"),
        doc="the on-board catalogue's and the camera's detection limit [mag]",
    )
    epoch: float = setting(
        2025.0,
        check=between(1900.0, 2100.0, what="a year in"),
        doc="proper motion applied to this epoch [year] (catalogue.py)",
    )
    merge_arcsec: float = setting(
        140.0,
        unit="arcsec",
        check=between(0.0, 3600.0, "arcsec"),
        doc="catalogue pairs closer than this are one entry (unresolved by the camera)",
    )
    sigma_px: float = setting(
        0.2, unit="px", check=Check(lambda v: 0.0 < v <= 10.0, "in (0, 10] px"), doc="centroid noise per axis (1σ)"
    )
    p_detect: float = setting(
        0.95, check=Check(lambda v: 0.0 < v <= 1.0, "in (0, 1]"), doc="probability that each star in view is detected"
    )
    false_stars: int = setting(
        0, check=between(0, 1000, what="an integer in"), doc="false stars per frame (a fixed number) ..."
    )
    false_rate: float = setting(
        0.0,
        check=between(0.0, 1000.0, "per frame"),
        doc="... plus a Poisson number of false stars with this mean per frame",
    )
    mag_sigma: float = setting(0.1, check=between(0.0, 2.0, "mag"), doc="instrument magnitude noise [mag]")
    cache_dir: str | None = setting(None, doc="the catalogue cache", default_text="catalogue.default_cache_dir()")


def read_cameras(cfg: dict) -> dict[str, CameraConfig]:
    """The ``star_cameras`` section, read strictly."""
    return read_entries(CameraConfig, cfg.get(SECTION), SECTION)


CAMERAS = SectionReader(SECTION, dict[str, CameraConfig], "the star cameras (node kind star_camera)")


def camera_config(cfg: dict, name: str) -> CameraConfig:
    cameras = read_cameras(cfg)
    if name not in cameras:
        raise ScenarioError(f"unknown star camera '{name}'; the scenario's star_cameras: {sorted(cameras)}")
    return cameras[name]


def _spec(cfg: dict, name: str) -> NodeSpec:
    return NodeSpec(
        name,
        "star_camera",
        publishes={measurement_topic(name): STAR_CENTROIDS_TYPE, star_truth_topic(name): STAR_CENTROIDS_TYPE},
        subscribes={TRUTH_TOPIC: TRUTH_TYPE},
    )


def _check(cfg: dict, name: str) -> None:
    camera_config(cfg, name)
    truth = read_truth(cfg).model
    if truth != "lvlh_camera":
        raise ScenarioError(f"star camera '{name}' needs the attitude truth 'truth.model: lvlh_camera', got {truth!r}")


def _star_camera(cfg: dict, name: str, run: dict | None = None):
    """The camera's core (star_tracker.star_camera.StarCameraStage), its random draws seeded by the run."""
    from star_tracker.star_camera import StarCameraStage  # catalogue, camera, frames: scipy, not for every node

    seed = int((run or {}).get("seed", scenario_seed(cfg)))
    rng = np.random.default_rng([seed, 3000 + sorted(read_cameras(cfg)).index(name)])
    return StarCameraStage(name, camera_config(cfg, name), rng, read_truth(cfg))


STAR_CAMERA = NodeKind(
    "star_camera",
    "sensor",
    "bench_engine.stage_node:StageNode",
    instances=lambda cfg, requested: list(read_cameras(cfg)),
    spec=_spec,
    check=_check,
    stage=_star_camera,
)
