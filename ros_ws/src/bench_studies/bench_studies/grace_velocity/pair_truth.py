"""grace_velocity's truth: a leader-follower pair in ECI (paper 002's GRACE satellites), registered as truth
models ``pair_j2`` (two-body + J2) and ``pair_hifi`` (zonal field to ``zonal_degree`` and drag): their keys and
registration are in pair_settings.py (cheap to import), the integration here.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.integrate import solve_ivp

from bench_engine.timegrid import TimeGrid
from bench_studies.grace_velocity.pair_settings import LABELS, Pair
from orbit_sim.geopotential import ZONALS, drag_acceleration, zonal_acceleration
from orbit_sim.truth import Earth, Truth

RTOL, ATOL = 1.0e-13, 1.0e-8
"""The truth must be more accurate than the most accurate estimator judged against it: the dynamic orbit fit
knows each satellite's position to a fraction of a millimetre. At looser tolerances (rtol 1e-11, atol 1e-6) each
satellite's position drifts by about the fit's sigma over half a day (the baseline far less: the two satellites'
errors are alike), which shows as the fit's per-satellite NEES rising with time in every seed; at these the drift
stays far below it, at a higher integration cost. tests/test_grace_filters.py measures the drift against a
reference at rtol 2.3e-14."""


def pair_rate(
    t: float,
    y: np.ndarray,
    mu: float,
    re: float,
    zonals: dict[int, float],
    ballistic: tuple[float, float],
    rotation_rate: float,
) -> np.ndarray:
    """d/dt of both satellites' ECI states stacked (12,): zonal gravity plus drag (B = 0: none)."""
    s = y.reshape(2, 6)
    a = zonal_acceleration(s[:, :3], mu, re, zonals)
    if any(ballistic):
        for k, b in enumerate(ballistic):
            if b:
                a[k] += drag_acceleration(s[k, :3], s[k, 3:], b, rotation_rate, re)
    return np.concatenate([s[:, 3:], a], axis=1).ravel()


def pair_truth(sec: Pair, model: str, earth: Earth, grid: TimeGrid, seed: int = 0) -> Truth:
    """Both satellites integrated together (DOP853) and sampled on the step grid; ``pair_hifi`` with the zonal
    field to ``zonal_degree`` and drag, ``pair_j2`` with J2 only."""
    a = sec.leader.semi_major_axis(earth.mu)
    x1 = sec.leader.state(earth.mu)
    x2 = replace(sec.leader, M_deg=sec.leader.M_deg - np.degrees(sec.separation_m / a)).state(earth.mu)
    if model == "pair_hifi":
        zonals = {n: (earth.j2 if n == 2 else ZONALS[n]) for n in range(2, sec.zonal_degree + 1)}
        ballistic = sec.ballistic
    else:
        zonals, ballistic = {2: earth.j2}, [0.0, 0.0]
    times = np.concatenate([[0.0], grid.times()]) if grid.start_ns > 0 else grid.times()
    sol = solve_ivp(
        pair_rate,
        (times[0], times[-1]),
        np.concatenate([x1, x2]),
        method="DOP853",
        t_eval=times,
        rtol=RTOL,
        atol=ATOL,
        args=(earth.mu, earth.re, zonals, tuple(float(b) for b in ballistic), earth.rotation_rate),
    )
    if not sol.success:
        raise RuntimeError(f"pair propagation failed: {sol.message}")
    y = sol.y.T
    states = np.hstack([y, y[:, 6:] - y[:, :6]])
    return Truth(grid, states[1:] if grid.start_ns > 0 else states, LABELS, "eci")
