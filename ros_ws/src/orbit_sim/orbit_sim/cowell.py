"""Cowell's method: direct numerical integration of the two-body + J2 equations (paper 000, eq. 7).

``propagate`` is the truth integrator (scipy's DOP853, tight tolerances). ``rk4`` is the filters'
fixed-step predictor.
"""

from __future__ import annotations

import math

import numpy as np

from .constants import J2_EARTH, MU_EARTH, R_EARTH
from .gravity import state_derivative

Num = float | np.ndarray
"""A scalar (one state) or an array (one entry per state in a batch)."""


def propagate(
    state0: np.ndarray,
    times: np.ndarray,
    mu: float = MU_EARTH,
    j2: float = J2_EARTH,
    re: float = R_EARTH,
    rtol: float = 1e-12,
    atol: float = 1e-9,
) -> np.ndarray:
    """Integrate state0 (6,), given at times[0], and return the states at ``times`` (K,), shape (K, 6).

    ``times`` must be monotonic (increasing or decreasing). atol applies to metres and m/s alike:
    1e-9 is far below the relative tolerance on LEO positions (~7e6 m) and velocities (~7e3 m/s).
    """
    from scipy.integrate import solve_ivp  # scipy.integrate: every node reads the truth kind, one integrates

    times = np.asarray(times, dtype=float)
    state0 = np.asarray(state0, dtype=float)
    if times.size == 1 or times[-1] == times[0]:
        return np.tile(state0, (times.size, 1))
    sol = solve_ivp(
        state_derivative,
        (times[0], times[-1]),
        state0,
        method="DOP853",
        t_eval=times,
        rtol=rtol,
        atol=atol,
        args=(mu, j2, re),
    )
    if not sol.success:
        raise RuntimeError(f"Cowell propagation failed: {sol.message}")
    return sol.y.T


def state_rate(x: Num, y: Num, z: Num, vx: Num, vy: Num, vz: Num, mu: float, k: float) -> tuple:
    """Component-wise twin of gravity.state_derivative (k = mu J2 Re^2 / 2).

    Works unchanged on Python floats (one state) and on numpy arrays (one entry per state).
    """
    r2 = x * x + y * y + z * z
    inv_r2 = 1.0 / r2
    inv_r3 = inv_r2 / r2**0.5
    inv_r5 = inv_r3 * inv_r2
    zz = 15.0 * z * z * inv_r5 * inv_r2
    g = k * (zz - 3.0 * inv_r5) - mu * inv_r3
    return vx, vy, vz, g * x, g * y, (g - 6.0 * k * inv_r5) * z


def _rk4_steps(s: tuple, h: float, n: int, mu: float, k: float) -> tuple:
    """n classical RK4 steps of size h on the components s = (x, y, z, vx, vy, vz)."""
    for _ in range(n):
        a = state_rate(*s, mu, k)
        b = state_rate(*(si + 0.5 * h * ai for si, ai in zip(s, a)), mu, k)
        c = state_rate(*(si + 0.5 * h * bi for si, bi in zip(s, b)), mu, k)
        d = state_rate(*(si + h * ci for si, ci in zip(s, c)), mu, k)
        w = h / 6.0
        s = tuple(si + w * (ai + 2.0 * (bi + ci) + di) for si, ai, bi, ci, di in zip(s, a, b, c, d))
    return s


def rk4(
    x: np.ndarray, dt: float, mu: float = MU_EARTH, j2: float = J2_EARTH, re: float = R_EARTH, max_step: float = 10.0
) -> np.ndarray:
    """Fixed-step RK4 propagation of one state (6,) or a batch (m, 6) by dt seconds (dt may be < 0).

    The interval is split into ceil(|dt| / max_step) equal sub-steps. Speed matters here: the filters
    call this every 0.1 s scan within their per-step budgets (scripts/bench_filters.py). numpy's per-call
    overhead on tiny arrays would dominate gravity.state_derivative on one (6,) state, so the same formula is
    hand-written component-wise: one state runs in Python floats, a batch (m, 6) runs the identical code on
    numpy columns (one array op per term).
    """
    x = np.asarray(x, dtype=float)
    if dt == 0.0:
        return x.copy()
    n = max(1, math.ceil(abs(dt) / max_step))
    h = dt / n
    k = 0.5 * mu * j2 * re * re
    if x.ndim == 1:
        return np.array(_rk4_steps(tuple(x.tolist()), h, n, mu, k))
    return np.column_stack(_rk4_steps(tuple(x.T), h, n, mu, k))
