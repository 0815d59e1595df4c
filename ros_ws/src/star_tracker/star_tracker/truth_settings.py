"""The star tracker's truth model ``lvlh_camera`` as the graph and the settings reference see it: its keys of the
``truth`` section and the state it publishes, registered in tracking_bench.truth_models. Cheap to import (every
node reads the truth's labels to build the graph); the attitude itself is computed in truth_model.py.
"""

from __future__ import annotations

from dataclasses import dataclass

from bench_engine.labels import ANGULAR_RATE, QUATERNION
from bench_engine.settings import Check, Settings, at_least, between, setting
from orbit_sim.truth import TruthModel
from star_tracker.options import BORESIGHTS

LABELS = QUATERNION + ANGULAR_RATE
"""The camera-from-ICRS attitude quaternion, scalar first, then the body rate in the camera frame [rad/s]."""
FRAME = "icrs"


@dataclass(frozen=True, kw_only=True)
class CameraTruth(Settings):
    """``lvlh_camera``: a camera fixed in LVLH on a circular orbit (truth_model.py)."""

    boresight: str = setting(
        "zenith",
        choices=BORESIGHTS,
        doc="zenith: a straight drift across the sky (the constant-velocity case); normal: a "
        "rotation about the boresight (the coordinated-turn case)",
    )
    jitter_deg_s: float = setting(
        0.0, unit="deg/s", check=between(0.0, 90.0, "deg/s"), doc="J: the boresight rate's jitter, uniform in ±J"
    )
    jitter_hold: int = setting(10, check=at_least(1), doc="frames each jitter value is held")
    jitter_seed: int | None = setting(
        None,
        check=Check(lambda v: v >= 0, "an integer >= 0 or null (the run's seed)"),
        doc="the jitter sequence's generator: null = the run's seed (each Monte Carlo "
        "run draws its own jitter); an integer fixes the sequence across runs",
    )
    altitude_m: float = setting(
        700e3,
        unit="m",
        check=Check(lambda v: 0.0 < v < 1e8, "in (0, 1e8) m"),
        doc="the circular orbit's altitude above the equatorial radius",
    )
    inclination_deg: float = setting(30.0, unit="deg", check=between(0.0, 180.0), doc="the orbit's inclination")
    raan_deg: float = setting(30.0, unit="deg", doc="the orbit's right ascension of the ascending node")
    arg_latitude0_deg: float = setting(50.0, unit="deg", doc="argument of latitude at the epoch")


CAMERA_TRUTH = TruthModel(CameraTruth, "star_tracker.truth_model:camera_truth", LABELS, FRAME, seeded=True)
