"""Two-body + J2 orbit dynamics in ECI for orbit filters (paper 000, eqs. 6-7 and 17-18).

Propagation is orbit_sim.cowell.rk4 (fixed-step RK4, sub-steps of at most ``max_step`` seconds).

Transition matrix. The variational equations of x' = [v, a(r)] are Phi' = A(t) Phi with
A = [[0, I], [G(r(t)), 0]] and G = d a / d r the gravity gradient. Over each RK4 sub-step of length h the
gradient is frozen at the sub-step's midpoint position r + v h / 2, and the frozen linear system is
solved exactly:
    Phi_h = [[C, S], [G S, C]],   C = sum_k G^k h^(2k) / (2k)!,   S = sum_k G^k h^(2k+1) / (2k+1)!
truncated after the G terms: |G| h^2 <= 2.6e-6 s^-2 * (10 s)^2 = 2.6e-4, so the first omitted term,
G^2 h^4 / 24, is below 3e-9 of the kept ones. Freezing G at the midpoint is exact to first order in h for the
blocks whose integrals weight G symmetrically over the sub-step (d v / d r = int G dt, d r / d v; the
second-order remainder is ~4e-5 of d v / d r at h = 10 s); d r / d r and d v / d v
weight it towards the start / end, so their gravity-gradient part (G h^2 / 2) carries a relative error
~ h |dG/dt| / (6 |G|) ~ 4e-3 for h = 10 s (absolute ~5e-7), and 4e-5 (absolute ~5e-13) on the filters'
0.1 s steps. tests/test_kf_ekf_ukf.py checks this against finite differences of ``propagate``. The cost
is one gravity-gradient evaluation per sub-step, versus four plus 6x6 products for RK4-integrated
variational equations: the EKF's per-step budget is why (scripts/bench_filters.py). For the same reason the
gradient is evaluated by ``orbit_sim.gravity.gravity_gradient`` on Python floats, cheaper than numpy calls on
one 3-vector.

Trajectory (``trajectory``, for the batch re-solves of tracker_filters/relinearisation.py). The states and
Phi(t_j, t0) at every scan time of a pass come from one integration of the state and the variational
equations Phi' = A(t) Phi (42 components) by scipy's DOP853 with dense output at the scan times, far fewer
right-hand-side evaluations than the per-scan ``propagate`` + ``transition_matrix`` chain, which it matches to
that chain's own midpoint-freezing error (tests/test_relinearisation.py; costs: scripts/bench_resolve.py).

Process noise. The paper's eq. 18, 2 sigma_m^2 tau_m [[T^3/3, T^2/2], [T^2/2, T]] padded with zeros, is a
garbled Singer-model block that leaves y and z noiseless. This model uses the standard continuous white-
acceleration noise on each of the three axes, discretised exactly:
    Q_axis = q [[dt^3/3, dt^2/2], [dt^2/2, dt]],   q = sigma_accel^2  [m^2/s^3],
i.e. ``sigma_accel`` is the square root of the acceleration noise's power spectral density, in m/s^(3/2).
"""

from __future__ import annotations

import math

import numpy as np

from bench_engine.labels import ORBIT
from bench_models.linear_models import white_acceleration_q
from orbit_sim.constants import J2_EARTH, MU_EARTH, R_EARTH
from orbit_sim.cowell import rk4, state_rate
from orbit_sim.gravity import gravity_gradient

VARIATIONAL_RTOL = 1e-12
VARIATIONAL_ATOL = 1e-9
"""``trajectory``'s DOP853 tolerances (as orbit_sim.cowell.propagate; atol in m, m/s and Phi's units)."""


class OrbitJ2Dynamics:
    """DynamicsModel: ECI state [x y z vx vy vz] under two-body + J2 gravity with white-acceleration noise."""

    labels = ORBIT
    frame = "eci"

    def __init__(
        self,
        sigma_accel: float,
        mu: float = MU_EARTH,
        j2: float = J2_EARTH,
        re: float = R_EARTH,
        max_step: float = 10.0,
    ) -> None:
        if not sigma_accel >= 0.0:
            raise ValueError(f"sigma_accel must be >= 0, got {sigma_accel}")
        if not max_step > 0.0:
            raise ValueError(f"max_step must be > 0, got {max_step}")
        self.sigma_accel = float(sigma_accel)
        self.mu = float(mu)
        self.j2 = float(j2)
        self.re = float(re)
        self.max_step = float(max_step)
        self._q_cache: tuple[tuple[float, float], np.ndarray] = ((float("nan"), 0.0), np.zeros((6, 6)))

    def propagate(self, x: np.ndarray, dt: float) -> np.ndarray:
        """RK4 propagation of one state (6,) or a batch (m, 6) by dt seconds."""
        return rk4(x, dt, self.mu, self.j2, self.re, self.max_step)

    def transition_matrix(self, x: np.ndarray, dt: float) -> np.ndarray:
        """d propagate(x, dt) / d x (6, 6): midpoint-frozen variational equations (see module docstring)."""
        x = np.asarray(x, dtype=float)
        if dt == 0.0:
            return np.eye(6)
        n = max(1, math.ceil(abs(dt) / self.max_step))
        h = dt / n
        phi = self._substep_phi(x, h)
        for _ in range(n - 1):
            x = self.propagate(x, h)
            phi = self._substep_phi(x, h) @ phi
        return phi

    def _substep_phi(self, x: np.ndarray, h: float) -> np.ndarray:
        """Transition of x' = [[0, I], [G, 0]] x over h with G frozen at r + v h / 2, to first order in G h^2."""
        rx, ry, rz = (x[0:3] + 0.5 * h * x[3:6]).tolist()
        G = gravity_gradient(rx, ry, rz, self.mu, self.j2, self.re)
        h2 = h * h
        C = G * (0.5 * h2)
        S = G * (h2 * h / 6.0)
        C.flat[::4] += 1.0
        S.flat[::4] += h
        phi = np.empty((6, 6))
        phi[0:3, 0:3] = C
        phi[0:3, 3:6] = S
        phi[3:6, 0:3] = G @ S
        phi[3:6, 3:6] = C
        return phi

    def trajectory(self, x0: np.ndarray, t0: float, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """States (m, 6) and transition matrices Phi(t_j, t0) (m, 6, 6) at ``times`` (m,) from the state x0
        (6,) at t0: one DOP853 integration of the state and variational equations (module docstring).

        Times may be irregular, repeated, equal to t0 or on both sides of it (one integration per side).
        """
        times = np.asarray(times, dtype=float)
        y0 = np.concatenate((np.asarray(x0, dtype=float), np.eye(6).ravel()))
        unique, inverse = np.unique(times, return_inverse=True)
        after = unique >= t0
        rows = np.concatenate(
            (self._variational(y0, t0, unique[~after][::-1])[::-1], self._variational(y0, t0, unique[after]))
        )[inverse.ravel()]
        return rows[:, 0:6], rows[:, 6:].reshape(-1, 6, 6)

    def _variational(self, y0: np.ndarray, t0: float, times: np.ndarray) -> np.ndarray:
        """[state, Phi flattened] (k, 42) at ``times``, ordered away from t0 (all on one side of it)."""
        if times.size == 0 or times[-1] == t0:
            return np.tile(y0, (times.size, 1))
        from scipy.integrate import solve_ivp  # scipy.integrate: only a filter node that re-solves its pass

        sol = solve_ivp(
            self._variational_derivative,
            (t0, times[-1]),
            y0,
            method="DOP853",
            t_eval=times,
            rtol=VARIATIONAL_RTOL,
            atol=VARIATIONAL_ATOL,
        )
        if not sol.success:
            raise RuntimeError(f"variational equations failed: {sol.message}")
        return sol.y.T

    def _variational_derivative(self, t: float, y: np.ndarray) -> np.ndarray:
        """d/dt [r, v, Phi] = [v, a(r), [[Phi_v], [G(r) Phi_r]]] with Phi (6, 6) flattened row-major.

        State rate and gradient on Python floats (orbit_sim.cowell.state_rate, gravity_gradient): cheaper than
        the numpy ``gravity.acceleration`` on one 3-vector, at this call rate.
        """
        out = np.empty(42)
        out[0:6] = state_rate(*y[0:6].tolist(), self.mu, 0.5 * self.mu * self.j2 * self.re * self.re)
        out[6:24] = y[24:42]
        x, y_, z = y[0:3].tolist()
        out[24:42] = (gravity_gradient(x, y_, z, self.mu, self.j2, self.re) @ y[6:24].reshape(3, 6)).ravel()
        return out

    def process_noise(self, x: np.ndarray, dt: float) -> np.ndarray:
        """3-axis white-acceleration Q for a step of dt seconds (replaces the paper's eq. 18).

        The last Q is cached (the filters step at a fixed rate) and returned read-only. Steps computed as
        differences of absolute times differ in their last bits; a dt within 1e-9 (relative) of the cached
        one reuses it (Q changes by ~1e-9 relative, far below anything Q is known to).
        """
        key = (dt, self.sigma_accel)
        (cached_dt, cached_sigma), _ = self._q_cache
        if not (abs(dt - cached_dt) <= 1e-9 * abs(dt) and cached_sigma == self.sigma_accel):
            Q = white_acceleration_q(self.sigma_accel**2, dt, 3)
            Q.flags.writeable = False
            self._q_cache = (key, Q)
        return self._q_cache[1]
