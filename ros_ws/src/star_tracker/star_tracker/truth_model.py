"""The star tracker's truth model (registered as ``lvlh_camera`` in ``tracking_bench.truth_models``): the attitude
of a camera fixed in LVLH on the paper's circular orbit, with its boresight jitter (sky_motion.py), on the
scenario's time grid (one frame per step).

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

from bench_engine.config import Section
from bench_engine.labels import ANGULAR_RATE, QUATERNION
from bench_engine.timegrid import TimeGrid
from orbit_sim.truth import Truth
from star_tracker.sky_motion import BORESIGHTS, CircularOrbit, orbit_truth

LABELS = QUATERNION + ANGULAR_RATE
FRAME = "icrs"


def orbit_of(sec: Section):
    """The CircularOrbit of the truth section's orbit keys."""
    return CircularOrbit(altitude_m=sec.get("altitude_m", float, 700e3, lambda v: 0.0 < v < 1e8, "in (0, 1e8) m"),
                         inclination_deg=sec.get("inclination_deg", float, 30.0, lambda v: 0.0 <= v <= 180.0,
                                                 "in [0, 180]"),
                         raan_deg=sec.get("raan_deg", float, 30.0),
                         arg_latitude0_deg=sec.get("arg_latitude0_deg", float, 50.0))


def camera_truth(sec: Section, model: str, earth, grid: TimeGrid, seed: int = 0):
    """Truth (orbit_sim.truth.Truth) of the module docstring's section; ``seed`` is the run's seed."""
    boresight = sec.choice("boresight", BORESIGHTS, "zenith")
    jitter = sec.get("jitter_deg_s", float, 0.0, lambda v: 0.0 <= v <= 90.0, "in [0, 90] deg/s")
    hold = sec.get("jitter_hold", int, 10, lambda v: v >= 1, "an integer >= 1")
    fixed = sec.get("jitter_seed", int, None, lambda v: v >= 0, "an integer >= 0 or null (the run's seed)")
    seed = seed if fixed is None else fixed
    orbit = orbit_of(sec)
    truth = orbit_truth(orbit, grid.steps, grid.dt, boresight, jitter, np.random.default_rng([seed, 7]), hold)
    states = np.hstack([truth.quaternions, truth.rate])
    return Truth(grid, states, LABELS, FRAME)


camera_truth.seeded = True  # orbit_sim.truth.build_truth passes the run's seed
