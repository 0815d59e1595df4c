"""Star identification, tracking and attitude in the graph: the node kind ``star_tracker`` (role estimator)
for every entry of the scenario's ``star_trackers`` section that the run selects (``--estimators`` or the
scenario's ``estimators``). Each runs the per-frame core (pipeline.StarTrackerPipeline: lost-in-space → SNA or JPDAF
tracking → TRIAD or Wahba attitude) on one camera's centroids, so several trackers see identical frames.

    star_tracker_defaults: {camera: camera, motion: constant_velocity, sigma_a: 0.05}
    star_trackers:
      sna_triad:   {tracker: sna, solver: triad}
      jpdaf_wahba: {tracker: jpdaf, solver: wahba}

Keys (defaults merged with the entry): ``camera`` (a star_cameras entry; default the only one), ``tracker``
(sna, jpdaf), ``solver`` (triad, wahba), ``motion`` (constant_velocity, coordinated_turn: eqs. 14–16),
``aid`` (rate, jitter, none: pipeline.py), ``sigma_px`` (the σ the identifier, the SNA gate and the JPDAF's R
assume; default the camera's), ``sigma_a`` (JPDAF process noise, px/s²), ``p_detect`` (the JPDA's P_D),
``clutter_per_frame`` (the JPDA's false-star density × image area; default the camera's false-star rate, at
least 0.1), ``gate`` (δ on d², default the JPDA's), ``min_stars``, ``verify_sigmas``, ``max_misses``.

Publishes ``/NAME/estimate`` (bench_msgs/StateEstimate): the camera-from-ICRS quaternion, labels qw qx qy qz
(attitude.py), with the 3 × 3 covariance of the attitude error rotation (rad², camera frame; the scorer's
rx ry rz: bench_models.states), and the diagnostics ``stars`` (used in the fit), ``identified`` (centroids
with a star id), ``lost_in_space`` and ``reacquisitions`` (running counts of lost-in-space solves, and of
those after a lost lock) and ``filter_resets`` (no wall-clock time: a bag is reproduced bit for bit). A frame without an
attitude publishes no estimate; its reason is logged. ``/NAME/stars`` (bench_msgs/StarCentroids), every
frame: per measured centroid, the star id it was given (HIP, −1: none) and the position the attitude used
(filtered for the JPDAF; NaN if unused).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench_engine.config import ScenarioError, merge
from bench_engine.graph import ESTIMATE_TYPE, NodeKind, NodeSpec, estimate_topic, measurement_topic
from bench_engine.labels import QUATERNION
from bench_engine.settings import Check, SectionReader, Settings, between, read_entries, replaced, setting
from bench_engine.stage import Estimate, Outputs, python_log
from star_tracker.camera_stage import camera_config, read_cameras
from star_tracker.messages import STAR_CENTROIDS_TYPE, StarFrame
from star_tracker.options import AIDS, MOTIONS, SOLVERS, TRACKERS

SECTION = "star_trackers"
DEFAULTS = "star_tracker_defaults"
FRAME = "icrs"


def stars_topic(tracker: str) -> str:
    return f"/{tracker}/stars"


@dataclass(frozen=True, kw_only=True)
class TrackerConfig(Settings):
    """One entry of ``star_trackers``, over ``star_tracker_defaults`` (the module docstring)."""

    camera: str | None = setting(
        None, doc="the star_cameras entry whose frames it reads", default_text="the only camera"
    )
    tracker: str = setting(choices=TRACKERS, doc="star tracking: SNA or JPDAF")
    solver: str = setting(choices=SOLVERS, doc="attitude from the tracked stars: SVD Wahba or TRIAD")
    motion: str = setting(
        "constant_velocity", choices=MOTIONS, doc="the JPDAF's image-plane motion model (paper eqs. 14-16)"
    )
    aid: str = setting(
        "rate",
        choices=AIDS,
        doc="what the body rate compensates in the JPDAF's prediction (pipeline.StarTrackerPipeline.motion_for)",
    )
    sigma_px: float | None = setting(
        None,
        unit="px",
        check=Check(lambda v: 0.0 < v <= 10.0, "in (0, 10] px"),
        doc="the centroid σ the identifier, the SNA gate and the JPDAF's R assume",
        default_text="the camera's sigma_px",
    )
    sigma_a: float = setting(
        0.05,
        unit="px/s^2",
        check=Check(lambda v: 0.0 < v <= 1e4, "in (0, 1e4] px/s^2"),
        doc="the JPDAF's process noise",
    )
    p_detect: float = setting(0.95, check=Check(lambda v: 0.0 < v < 1.0, "in (0, 1)"), doc="the JPDA's P_D")
    clutter_per_frame: float | None = setting(
        None,
        check=Check(lambda v: 0.0 < v <= 1e4, "in (0, 1e4]"),
        doc="the JPDA's false-star density times the image area",
        default_text="the camera's false stars per frame, at least 0.1",
    )
    gate: float | None = setting(
        None,
        check=Check(lambda v: 0.0 < v <= 1e4, "in (0, 1e4]"),
        doc="the JPDA's gate δ on d²",
        default_text="the JPDA's",
    )
    min_stars: int = setting(3, check=between(3, 100, what="an integer in"), doc="stars an attitude needs")
    verify_sigmas: float = setting(
        6.0, check=between(1.0, 100.0), doc="the identification's verification threshold [σ]"
    )
    max_misses: int = setting(
        3, check=between(0, 100, what="an integer in"), doc="frames a tracked star may miss before it is dropped"
    )


def read_trackers(cfg: dict) -> dict[str, TrackerConfig]:
    """``star_trackers`` merged over ``star_tracker_defaults``, read strictly (the reader of both keys)."""
    defaults = cfg.get(DEFAULTS) or {}
    if not isinstance(defaults, dict):
        raise ScenarioError(f"'{DEFAULTS}' must be a mapping of settings, got {defaults!r}")
    cameras = list(read_cameras(cfg))
    own = cfg.get(SECTION) or {}
    if not isinstance(own, dict):
        raise ScenarioError(f"'{SECTION}' must be a mapping of keys, got {type(own).__name__}")
    trackers = read_entries(TrackerConfig, {n: merge(defaults, e or {}) for n, e in own.items()}, SECTION)
    for name, conf in trackers.items():
        if not cameras:
            raise ScenarioError(f"star tracker '{name}' needs a camera: the scenario has no 'star_cameras'")
        if conf.camera is None and len(cameras) > 1:
            raise ScenarioError(f"missing key '{conf.where('camera')}' (the scenario has cameras {cameras})")
        if conf.camera is not None and conf.camera not in cameras:
            raise ScenarioError(f"'{conf.where('camera')}' must be one of {cameras}, got {conf.camera!r}")
        trackers[name] = replaced(conf, camera=conf.camera or cameras[0])
    return trackers


TRACKERS_SECTION = SectionReader(
    SECTION, dict[str, TrackerConfig], "the star trackers (node kind star_tracker: estimators)", read_trackers
)
TRACKER_DEFAULTS = SectionReader(
    DEFAULTS,
    TrackerConfig,
    "defaults of every star_trackers entry: any of its keys",
    read_trackers,
    defaults_of=SECTION,
)


def tracker_config(cfg: dict, name: str) -> TrackerConfig:
    trackers = read_trackers(cfg)
    if name not in trackers:
        raise ScenarioError(f"unknown star tracker '{name}'; the scenario's star_trackers: {sorted(trackers)}")
    return trackers[name]


def build_pipeline(cfg: dict, name: str):
    """The pipeline of tracker ``name`` (its camera's catalogue and geometry: pipeline.pipeline_for)."""
    from star_tracker.pipeline import pipeline_for  # catalogue, Pyramid, JPDAF: scipy, not for every node

    conf = tracker_config(cfg, name)
    return pipeline_for(conf, camera_config(cfg, conf.camera))


class StarTrackerStage:
    """One tracker/solver on one camera's frames (module docstring)."""

    def __init__(self, cfg: dict, name: str, run: dict | None = None) -> None:
        self.name = name
        self.pipeline = build_pipeline(cfg, name)
        self.camera = self.pipeline.camera
        self.topic, self.stars = estimate_topic(name), stars_topic(name)
        self.counts = {"lost_in_space": 0, "reacquisitions": 0}
        self.had_lock = False
        self.log = python_log(name)

    def on_input(self, topic: str, frame: StarFrame) -> Outputs:
        uv = self.camera.from_tangent(frame.xy)
        mags = frame.magnitudes if len(frame.magnitudes) == len(uv) else None
        result = self.pipeline.process(uv, mags, frame.t, frame.body_rate, frame.jitter_rate)
        if result.mode == "lost_in_space":
            self.counts["lost_in_space"] += 1
            if result.ok and self.had_lock:
                self.counts["reacquisitions"] += 1
                self.log("info", f"step {frame.step}: re-acquired lost-in-space")
        self.had_lock = self.had_lock or result.ok
        ids = np.where(result.index >= 0, self.pipeline.catalogue.ids[np.maximum(result.index, 0)], -1)
        used = np.full((len(uv), 2), np.nan)
        used[result.star_rows] = self.camera.to_tangent(result.star_uv)
        out: Outputs = [
            (
                self.stars,
                StarFrame(
                    frame.step,
                    frame.t_ns,
                    FRAME,
                    self.name,
                    used,
                    np.asarray(frame.magnitudes, dtype=float),
                    frame.sigma,
                    frame.body_rate,
                    frame.jitter_rate,
                    ids,
                ),
            )
        ]
        if not result.ok:
            self.log("info", f"step {frame.step}: no attitude ({result.reason})")
            return out
        sol = result.attitude
        diagnostics = {
            "stars": float(sol.n_stars),
            "identified": float(np.sum(result.index >= 0)),
            **{k: float(v) for k, v in self.counts.items()},
            "filter_resets": float(self.pipeline.filter_resets),
        }
        out.append(
            (
                self.topic,
                Estimate(
                    frame.step,
                    frame.t_ns,
                    FRAME,
                    self.name,
                    list(QUATERNION),
                    sol.quaternion,
                    sol.covariance,
                    float("nan"),
                    diagnostics,
                ),
            )
        )
        return out


def _spec(cfg: dict, name: str) -> NodeSpec:
    conf = tracker_config(cfg, name)
    return NodeSpec(
        name,
        "star_tracker",
        publishes={estimate_topic(name): ESTIMATE_TYPE, stars_topic(name): STAR_CENTROIDS_TYPE},
        subscribes={measurement_topic(conf.camera): ""},
        labels={estimate_topic(name): QUATERNION},
    )


def _check(cfg: dict, name: str) -> None:
    """Build the tracker's pipeline once at validation: a bad key stops the launch, and node processes forked
    from the launcher inherit the camera's k-vector (star_camera.pair_table) instead of each building it."""
    build_pipeline(cfg, name)


STAR_TRACKER = NodeKind(
    "star_tracker",
    "estimator",
    "bench_engine.stage_node:StageNode",
    instances=lambda cfg, names: list(names),
    spec=_spec,
    check=_check,
    stage=StarTrackerStage,
    claims=lambda cfg: list(read_trackers(cfg)),
)
