"""grace_velocity's truth: a leader-follower pair in ECI (paper 002's GRACE satellites), registered as truth
models ``pair_j2`` (two-body + J2) and ``pair_hifi`` (zonal field to ``zonal_degree`` and drag).

    truth:
      model: pair_hifi
      leader: {a: 6858137.0, e: 0.001, i_deg: 89.0, raan_deg: 0.0, argp_deg: 0.0, M_deg: 0.0}
      separation_m: 220000.0      # the follower trails on the same orbit, M lower by separation / a
      ballistic: [0.0045, 0.0047] # C_d A / m of leader and follower [m^2/kg] (pair_hifi)
      zonal_degree: 6             # J2 .. J6 (pair_hifi)

Published state (frame "eci"): leader ``x1 .. vz1``, follower ``x2 .. vz2`` and their baseline
``bx .. bvz`` = follower - leader, 18 components, so sensors of either satellite and of the baseline read
the components they need (bench_models.labelled).
"""
from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from bench_engine.config import ScenarioError, Section
from bench_engine.labels import ORBIT
from bench_engine.timegrid import TimeGrid
from orbit_sim.geopotential import ZONALS, drag_acceleration, zonal_acceleration
from orbit_sim.truth import Earth, Truth, orbit_state, semi_major_axis

LABELS = tuple(f"{c}{s}" for s in ("1", "2") for c in ORBIT) + (
    "bx", "by", "bz", "bvx", "bvy", "bvz")
RTOL, ATOL = 1.0e-13, 1.0e-8
"""The truth must be more accurate than the most accurate estimator judged against it: the dynamic orbit fit
knows each satellite's position to a fraction of a millimetre. At looser tolerances (rtol 1e-11, atol 1e-6) each
satellite's position drifts by about the fit's sigma over half a day (the baseline far less: the two satellites'
errors are alike), which shows as the fit's per-satellite NEES rising with time in every seed; at these the drift
stays far below it, at a higher integration cost. tests/test_grace_filters.py measures the drift against a
reference at rtol 2.3e-14."""


def pair_rate(t: float, y: np.ndarray, mu: float, re: float, zonals: dict[int, float], ballistic: tuple[float, float],
              rotation_rate: float) -> np.ndarray:
    """d/dt of both satellites' ECI states stacked (12,): zonal gravity plus drag (B = 0: none)."""
    s = y.reshape(2, 6)
    a = zonal_acceleration(s[:, :3], mu, re, zonals)
    if any(ballistic):
        for k, b in enumerate(ballistic):
            if b:
                a[k] += drag_acceleration(s[k, :3], s[k, 3:], b, rotation_rate, re)
    return np.concatenate([s[:, 3:], a], axis=1).ravel()


def _follower_section(leader: dict, separation: float, a: float) -> dict:
    shifted = dict(leader)
    shifted["M_deg"] = float(leader.get("M_deg", 0.0)) - np.degrees(separation / a)
    return shifted


def pair_truth(sec: Section, model: str, earth: Earth, grid: TimeGrid) -> Truth:
    """Both satellites integrated together (DOP853) and sampled on the step grid."""
    leader = sec.get("leader", dict)
    separation = sec.positive("separation_m")
    a = semi_major_axis(Section(dict(leader), "truth.leader"), earth.mu)
    x1 = orbit_state(Section(dict(leader), "truth.leader"), earth.mu)
    x2 = orbit_state(Section(_follower_section(leader, separation, a), "truth.leader"), earth.mu)
    if model == "pair_hifi":
        degree = sec.get("zonal_degree", int, 6, lambda v: 2 <= v <= max(ZONALS), f"in 2..{max(ZONALS)}")
        ballistic = sec.get("ballistic", list, [0.0, 0.0])
        if len(ballistic) != 2 or any(not isinstance(b, (int, float)) or b < 0 for b in ballistic):
            raise ScenarioError(f"'truth.ballistic' must be two values >= 0 (C_d A / m of leader and follower, "
                                f"m^2/kg), got {ballistic!r}")
        zonals = {n: (earth.j2 if n == 2 else ZONALS[n]) for n in range(2, degree + 1)}
    else:
        sec.mark("zonal_degree", "ballistic")
        zonals, ballistic = {2: earth.j2}, [0.0, 0.0]
    times = np.concatenate([[0.0], grid.times()]) if grid.start_ns > 0 else grid.times()
    sol = solve_ivp(pair_rate, (times[0], times[-1]), np.concatenate([x1, x2]), method="DOP853", t_eval=times,
                    rtol=RTOL, atol=ATOL,
                    args=(earth.mu, earth.re, zonals, tuple(float(b) for b in ballistic), earth.rotation_rate))
    if not sol.success:
        raise RuntimeError(f"pair propagation failed: {sol.message}")
    y = sol.y.T
    states = np.hstack([y, y[:, 6:] - y[:, :6]])
    return Truth(grid, states[1:] if grid.start_ns > 0 else states, LABELS, "eci")
