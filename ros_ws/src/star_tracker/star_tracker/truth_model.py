"""The star tracker's truth model ``lvlh_camera`` (its keys and registration: truth_settings.py): the attitude of a
camera fixed in LVLH on the paper's circular orbit, with its boresight jitter (sky_motion.py), on the scenario's
time grid (one frame per step).

    truth:
      model: lvlh_camera
      boresight: zenith          # zenith: straight drift (constant-velocity case); normal: rotation about the
                                 # boresight (coordinated-turn case)
      jitter_deg_s: 0.1          # J: boresight rate uniform in ±J (deg/s), held jitter_hold frames (paper: 10)
      jitter_hold: 10
      jitter_seed: null          # the jitter sequence's generator: null = the run's seed (each Monte Carlo run
                                 # draws its own jitter); an integer fixes the sequence across runs
      altitude_m: 700000.0
      inclination_deg: 30.0
      raan_deg: 30.0
      arg_latitude0_deg: 50.0

State per step: the camera-from-ICRS attitude quaternion (qw, qx, qy, qz), scalar first, qw >= 0 (A = R(q),
attitude.py: the convention of the attitude estimates), then the body rate (wx, wy, wz) in rad/s in the camera
frame; frame "icrs". The rate of step k is the rate over the interval from step k to k + 1 (sky_motion).
"""

from __future__ import annotations

import numpy as np

from bench_engine.timegrid import TimeGrid
from orbit_sim.truth import Truth
from star_tracker.sky_motion import CircularOrbit, orbit_truth
from star_tracker.truth_settings import FRAME, LABELS, CameraTruth


def orbit_of(sec: CameraTruth) -> CircularOrbit:
    """The circular orbit of the truth's keys."""
    return CircularOrbit(
        altitude_m=sec.altitude_m,
        inclination_deg=sec.inclination_deg,
        raan_deg=sec.raan_deg,
        arg_latitude0_deg=sec.arg_latitude0_deg,
    )


def camera_truth(sec: CameraTruth, model: str, earth, grid: TimeGrid, seed: int = 0) -> Truth:
    """Truth of the module docstring's section; ``seed`` is the run's seed (``jitter_seed`` overrides it)."""
    seed = seed if sec.jitter_seed is None else sec.jitter_seed
    truth = orbit_truth(
        orbit_of(sec),
        grid.steps,
        grid.dt,
        sec.boresight,
        sec.jitter_deg_s,
        np.random.default_rng([seed, 7]),
        sec.jitter_hold,
    )
    return Truth(grid, np.hstack([truth.quaternions, truth.rate]), LABELS, FRAME)
