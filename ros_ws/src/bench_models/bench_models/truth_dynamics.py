"""The truth's own dynamics as a model: the deterministic motion of orbit_sim's truth models, linearised along
the true trajectory (for the posterior CRB along the truth, tracker_filters.pcrb).

The truth models fly without process noise, so every model here has Q = 0.
- ``cowell_j2`` / ``cowell_twobody``: the ECI orbit, bench_models.orbit_dynamics.OrbitJ2Dynamics with the
  truth's J2 (or none).
- ``sgp4`` (a real satellite's element set, orbit_sim.tle): SGP4 has no partials here, so its motion is
  linearised as two-body + J2 (the Earth's J2) along the SGP4 trajectory: the bound is the J2 model's. From one
  state the two part by metres over a pass (tests/test_tle.py bounds it), far below a radar's range noise.
- ``hill_cw``: the exact Hill/Clohessy-Wiltshire relative motion, bench_models.relative_dynamics.CWDynamics
  with the chief's mean motion as the truth computes it (from |r| at the epoch).
- ``formation_j2`` / ``formation_twobody``: both spacecraft on two-body (+ J2), the state the deputy relative to
  the chief in the chief's LVLH frame. The chief's orbit is known (it is fixed by its initial state), so the
  relative state evolves deterministically but not autonomously: :class:`RelativeOrbitDynamics` gives the
  transition matrices along a trajectory (``transition_matrices``), from the deputy's ECI state-transition
  matrices (one DOP853 integration of the state and the variational equations:
  OrbitJ2Dynamics.trajectory) and the LVLH map at each end:
      F_k = L_{k+1}^{-1} Phi_d(t_{k+1}, t_k) L_k,   L = d x_eci / d x_lvlh = [[C^T, 0], [Omega C^T, C^T]],
  C the ECI->LVLH rotation and Omega the cross-product matrix of the frame's angular velocity (both of the
  chief at that time: orbit_sim.relative.lvlh_to_eci is affine in the relative state).
"""

from __future__ import annotations

import numpy as np

from bench_engine.config import ScenarioError
from bench_engine.labels import ORBIT
from bench_models.orbit_dynamics import OrbitJ2Dynamics
from bench_models.relative_dynamics import CWDynamics
from orbit_sim import cowell, gravity, relative
from orbit_sim.truth import build_earth, read_truth


class RelativeOrbitDynamics:
    """The relative LVLH state of a deputy about a chief whose ECI orbit (initial state ``chief0`` at t = 0)
    both fly on two-body + J2 (``j2`` = 0: two-body), without process noise. Time-varying: only
    ``transition_matrices`` along a trajectory and ``process_noise`` are defined."""

    labels = ORBIT
    frame = "lvlh"

    def __init__(self, chief0: np.ndarray, mu: float, j2: float, re: float) -> None:
        self.chief0 = np.asarray(chief0, dtype=float)
        self.mu, self.j2, self.re = mu, j2, re

    def lvlh_jacobians(self, chief: np.ndarray) -> np.ndarray:
        """d (deputy ECI state) / d (relative LVLH state) at chief states (K, 6): L above, (K, 6, 6)."""
        accel = gravity.acceleration(chief[:, :3], self.mu, self.j2, self.re)
        Ct = np.swapaxes(relative.lvlh_basis(chief), 1, 2)
        w = relative.frame_rate(chief, accel)
        Omega = np.zeros((len(chief), 3, 3))
        Omega[:, 0, 1], Omega[:, 0, 2], Omega[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
        Omega -= np.swapaxes(Omega, 1, 2)
        L = np.zeros((len(chief), 6, 6))
        L[:, :3, :3] = L[:, 3:, 3:] = Ct
        L[:, 3:, :3] = Omega @ Ct
        return L

    def transition_matrices(self, times: np.ndarray, states: np.ndarray) -> np.ndarray:
        """F_k (K-1, 6, 6) from times[k] to times[k+1] along the relative states (K, 6) at ``times`` (K,)."""
        times, states = np.asarray(times, dtype=float), np.asarray(states, dtype=float)
        grid = np.concatenate(([0.0], times)) if times[0] != 0.0 else times
        chief = cowell.propagate(self.chief0, grid, self.mu, self.j2, self.re)[len(grid) - len(times) :]
        accel = gravity.acceleration(chief[0, :3], self.mu, self.j2, self.re)
        deputy0 = relative.lvlh_to_eci(chief[0], states[0], accel)
        _, Phi = OrbitJ2Dynamics(0.0, self.mu, self.j2, self.re).trajectory(deputy0, times[0], times)
        L = self.lvlh_jacobians(chief)
        # F_k = L_{k+1}^{-1} Phi(t_{k+1}, t0) Phi(t_k, t0)^{-1} L_k
        step = np.linalg.solve(np.swapaxes(Phi[:-1], 1, 2), np.swapaxes(Phi[1:], 1, 2)).swapaxes(1, 2)
        return np.linalg.solve(L[1:], step @ L[:-1])

    def process_noise(self, x: np.ndarray, dt: float) -> np.ndarray:
        return np.zeros((6, 6))


def truth_dynamics(cfg: dict):
    """The dynamics of the scenario's ``truth`` section (module docstring); ScenarioError for a truth model
    without one here."""
    truth, earth = read_truth(cfg), build_earth(cfg)
    model = truth.model
    if model in ("cowell_j2", "cowell_twobody", "sgp4"):
        return OrbitJ2Dynamics(0.0, earth.mu, earth.j2 if model != "cowell_twobody" else 0.0, earth.re)
    if model in ("hill_cw", "formation_j2", "formation_twobody"):
        chief0 = truth.options.chief.state(earth.mu)
        if model == "hill_cw":
            return CWDynamics(float(np.sqrt(earth.mu / np.linalg.norm(chief0[:3]) ** 3)), 0.0)
        return RelativeOrbitDynamics(chief0, earth.mu, earth.j2 if model == "formation_j2" else 0.0, earth.re)
    raise ScenarioError(f"the truth model '{model}' has no dynamics model for a bound (bench_models.truth_dynamics)")
