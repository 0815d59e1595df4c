"""Relinearising the whole pass: Gauss-Newton re-solves of every scan since the first (batch MAP).

Why. When one coordinate is measured far more precisely than the others (a ground radar's range against its
angles: tens of metres against a degree, i.e. kilometres across the beam at orbital ranges), second-order terms of
the cross-range errors (the range shell's sag, position x velocity products in the range rate, the ring of
cross-range speeds that the range curvature pins down) stay comparable to the accumulated range precision
for most of the pass. A recursive filter linearises each scan once, at the estimate of its time; those
linearisation errors depend on the state error, which persists, so they are correlated from scan to scan
and lock into the estimate. With the true process noise (zero: the truth is the filter's own two-body + J2
model) nothing ever forgets them, and any Q > 0 makes the filter pessimistic once the true error keeps
shrinking. Re-linearising every scan at the current best estimate removes the lock-in (scripts/montecarlo.py
measures the consistency with and without it).

The problem. With a deterministic process model (Q = 0) every state is a function of the state x0 at the
time t0 of the first scan, x(t) = phi(x0, t). The maximum a posteriori x0 given the first-scan prior
N(m0, P0) and the scans z_j (noise R_j) minimises
    J(x0) = |W0 (x0 - m0)|^2 + sum_j |W_j r_j|^2,   r_j = z_j - h_j(phi(x0, t_j)) (angles wrapped),
with W^T W the inverse covariances. Gauss-Newton with A_j = W_j H_j Phi(t_j, t0):
    Lambda = W0^T W0 + sum_j A_j^T A_j,   g = W0^T W0 (m0 - x0) + sum_j A_j^T W_j r_j,   x0 += Lambda^-1 g,
the batch processor of orbit determination (Tapley, Schutz & Born 2004, section 4.6) and, with Q = 0, the
iterated Kalman smoother (Bell 1994). Steps that raise J are halved. The estimate at the last scan t_k is
phi(x0, t_k), its covariance Phi(t_k, t0) Lambda^-1 Phi(t_k, t0)^T (Laplace approximation).

Schedule. A filter with ``relinearise = g > 1`` runs its own recursive step on every scan and, once
``relinearise_from`` scans are stored and then every time their number has grown by the factor g, replaces
its estimate by the batch solution over all of them. The total work is about g / (g - 1) passes over the
final number of scans (1-3 passes per re-solve with the warm start).

Cost. ``PassBatch.linearise`` is vectorised over the scans when the dynamics offers ``trajectory`` (states
and Phi(t_j, t0) at every scan time from one DOP853 integration of the variational equations,
OrbitJ2Dynamics) and each measurement model ``h_series`` / ``jacobian_series`` (one ECI -> ENU rotation per
scan, GroundRadarModel): the scans of each model are stacked (each once, when first used),
A_j = W_j H_j Phi_j is one stacked product and Lambda, g and J are sums over the stack
(scripts/bench_resolve.py measures both paths). The per-scan loop of propagate / transition_matrix / h /
jacobian remains the path for any other DynamicsModel / MeasurementModel (e.g. the relative-motion models of
the formation scenarios) and gives the same answer to the integrators' agreement (tests/test_relinearisation.py).

Consistency. Once the pass has constrained the cross-range position the filters with re-solves are consistent;
before that no Gaussian estimator is (the posterior is a curved range shell with a ring of cross-range speeds,
and even the batch solution's Laplace covariance is overconfident). Earlier re-solves make the first seconds
worse, and a larger g saves work at some cost later in the pass. scripts/montecarlo.py and
scripts/leo_posterior_study.py measure both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_triangular

from bench_models.models import DynamicsModel, MeasurementModel
from tracker_filters.covariance import ensure_pd
from tracker_filters.kf import cholesky_lower, cholesky_solve

STEP_TOLERANCE = 1e-2
"""Gauss-Newton stops once the step's squared Mahalanobis length dx^T Lambda dx falls below this (a step
of 0.1 sigma); that last step is applied through the linearisation, with an error of second order in it."""
MAX_ITERATIONS = 10
MAX_HALVINGS = 6


def whitening(C: np.ndarray) -> np.ndarray:
    """W with W^T W = C^-1: the inverse of the lower Cholesky factor of C."""
    L = cholesky_lower(C)
    return solve_triangular(L, np.eye(L.shape[0]), lower=True)


@dataclass
class Scan:
    """One processed measurement, kept for re-linearisation."""

    t: float
    z: np.ndarray
    W: np.ndarray
    """Whitening of R (W^T W = R^-1)."""
    model: MeasurementModel


@dataclass
class Linearisation:
    """The batch cost and its Gauss-Newton normal equations at one x0, and the state at the last scan."""

    x0: np.ndarray
    cost: float
    info: np.ndarray
    """Lambda (n, n)."""
    gradient: np.ndarray
    """g (n,): the Gauss-Newton step is Lambda^-1 g."""
    x_last: np.ndarray
    phi_last: np.ndarray
    """Phi(t_last, t0)."""


@dataclass
class _ModelScans:
    """The scans of one measurement model, stacked."""

    model: MeasurementModel
    index: np.ndarray
    """Their positions among all scans (m,)."""
    t: np.ndarray
    z: np.ndarray
    W: np.ndarray
    """Whitenings (m, d, d)."""

    @classmethod
    def of(cls, scans: list[Scan], index: list[int]) -> _ModelScans:
        picked = [scans[j] for j in index]
        return cls(
            picked[0].model,
            np.array(index),
            np.array([s.t for s in picked]),
            np.array([s.z for s in picked]),
            np.array([s.W for s in picked]),
        )

    def extended(self, more: _ModelScans) -> _ModelScans:
        """These scans followed by ``more`` (same model)."""
        return _ModelScans(
            self.model, *(np.concatenate((getattr(self, k), getattr(more, k))) for k in ("index", "t", "z", "W"))
        )


class PassBatch:
    """The first-scan prior and every scan since: batch MAP of the state by Gauss-Newton.

    ``linearise`` is vectorised over the scans (module docstring) when ``vectorised`` is set, the dynamics
    has ``trajectory`` and every scan's model has ``h_series`` and ``jacobian_series``; otherwise it loops
    over the scans with the DynamicsModel / MeasurementModel methods. Both give the same answer.
    """

    def __init__(
        self, dynamics: DynamicsModel, m0: np.ndarray, P0: np.ndarray, t0: float, vectorised: bool = True
    ) -> None:
        self.dynamics = dynamics
        self.m0 = np.array(m0, dtype=float)
        self.W0 = whitening(np.asarray(P0, dtype=float))
        self.t0 = float(t0)
        self.vectorised = bool(vectorised)
        self.scans: list[Scan] = []
        self._last_R: tuple[np.ndarray, np.ndarray] = (np.empty((0, 0)), np.empty((0, 0)))
        self._stacked: tuple[int, np.ndarray, list[_ModelScans]] = (0, np.empty(0), [])

    def __len__(self) -> int:
        return len(self.scans)

    def add(self, t: float, z: np.ndarray, R: np.ndarray, model: MeasurementModel) -> None:
        """Keep one scan; its whitening is shared with the previous scan's when R is the same (a sensor's R
        rarely changes, and a Cholesky per scan would add to every filter step)."""
        R = np.asarray(R, dtype=float)
        if not np.array_equal(R, self._last_R[0]):
            self._last_R = (R.copy(), whitening(R))
        self.scans.append(Scan(float(t), np.array(z, dtype=float), self._last_R[1], model))

    def linearise(self, x0: np.ndarray) -> Linearisation:
        """Propagate x0 through every scan time; cost, normal equations and the state at the last scan."""
        x0 = np.array(x0, dtype=float)
        prior = self.W0 @ (self.m0 - x0)
        lin = Linearisation(x0, float(prior @ prior), self.W0.T @ self.W0, self.W0.T @ prior, x0, np.eye(x0.shape[0]))
        if self.scans and self._has_series():
            self._add_series(lin)
        else:
            self._add_loop(lin)
        return lin

    def _has_series(self) -> bool:
        """Whether the dynamics and every scan's model have the batched methods ``_add_series`` calls."""
        return (
            self.vectorised
            and hasattr(self.dynamics, "trajectory")
            and all(hasattr(g.model, "h_series") and hasattr(g.model, "jacobian_series") for g in self._stack()[1])
        )

    def _add_loop(self, lin: Linearisation) -> None:
        """Add every scan's terms to ``lin``, one scan at a time (propagate and transition_matrix per step)."""
        x, phi, t_prev = lin.x0, lin.phi_last, self.t0
        for s in self.scans:
            dt = s.t - t_prev
            if dt != 0.0:
                phi = self.dynamics.transition_matrix(x, dt) @ phi
                x = self.dynamics.propagate(x, dt)
                t_prev = s.t
            r = s.W @ s.model.residual(s.z, s.model.h(x, s.t))
            A = s.W @ s.model.jacobian(x, s.t) @ phi
            lin.info += A.T @ A
            lin.gradient += A.T @ r
            lin.cost += float(r @ r)
        lin.x_last, lin.phi_last = x, phi

    def _add_series(self, lin: Linearisation) -> None:
        """Add every scan's terms to ``lin``, vectorised: one ``trajectory`` call, then per measurement
        model one ``h_series`` and one ``jacobian_series`` call and the stacked A_j = W_j H_j Phi_j."""
        times, groups = self._stack()
        states, phis = self.dynamics.trajectory(lin.x0, self.t0, times)
        n = lin.x0.shape[0]
        for g in groups:
            x, phi = states[g.index], phis[g.index]
            r = np.einsum("mij,mj->mi", g.W, g.model.residual(g.z, g.model.h_series(x, g.t))).ravel()
            A = (g.W @ g.model.jacobian_series(x, g.t) @ phi).reshape(-1, n)
            lin.info += A.T @ A
            lin.gradient += A.T @ r
            lin.cost += float(r @ r)
        lin.x_last, lin.phi_last = states[-1], phis[-1]

    def _stack(self) -> tuple[np.ndarray, list[_ModelScans]]:
        """Every scan's time (k,) and the scans of each measurement model stacked; scans added since the
        last call are stacked and appended (once per scan)."""
        count, times, groups = self._stacked
        if count != len(self.scans):
            new = self.scans[count:]
            times = np.concatenate((times, [s.t for s in new]))
            by_model = {id(g.model): g for g in groups}
            new_by_model: dict[int, list[int]] = {}
            for j, s in enumerate(new, start=count):
                new_by_model.setdefault(id(s.model), []).append(j)
            for key, index in new_by_model.items():
                fresh = _ModelScans.of(self.scans, index)
                by_model[key] = by_model[key].extended(fresh) if key in by_model else fresh
            groups = list(by_model.values())
            self._stacked = (len(self.scans), times, groups)
        return times, groups

    def minimise(self, guess: np.ndarray) -> tuple[Linearisation, np.ndarray, int]:
        """Gauss-Newton from ``guess`` (a state at t0): the linearisation of lowest cost, the final step
        (below STEP_TOLERANCE, not applied to it) and the number of linearisations."""
        best = self.linearise(guess)
        passes = 1
        last_step = np.zeros_like(best.x0)
        for _ in range(MAX_ITERATIONS):
            step = cholesky_solve(cholesky_lower(best.info), best.gradient)
            if float(step @ best.gradient) <= STEP_TOLERANCE:
                last_step = step
                break
            for _ in range(MAX_HALVINGS + 1):
                trial = self.linearise(best.x0 + step)
                passes += 1
                if trial.cost <= best.cost:
                    break
                step = 0.5 * step
            else:
                break  # no decrease along the Gauss-Newton direction: best is a minimum to working accuracy
            best = trial
        return best, last_step, passes

    def solve(self, guess: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
        """Gauss-Newton from ``guess`` (a state at t0): (state (n,), covariance (n, n)) at the last scan and
        the number of linearisations. Never returns a solution of higher cost than the guess."""
        best, last_step, passes = self.minimise(guess)
        covariance = best.phi_last @ cholesky_solve(cholesky_lower(best.info), best.phi_last.T)
        return best.x_last + best.phi_last @ last_step, 0.5 * (covariance + covariance.T), passes


class Relinearising:
    """Mixin for a recursive Filter: replaces its estimate by the batch solution on a geometric schedule.

    The class it is mixed into calls ``_setup_relinearisation`` from its constructor. ``growth`` = 0 turns
    the re-solves off (the recursive filter alone, e.g. the paper's EKF and UKF).
    """

    def _setup_relinearisation(self, growth: float, first: int) -> None:
        if not (growth == 0.0 or growth > 1.0):
            raise ValueError(f"relinearise must be 0 (off) or a growth factor > 1, got {growth}")
        if not (isinstance(first, (int, np.integer)) and first >= 1):
            raise ValueError(f"relinearise_from must be a positive number of scans, got {first}")
        if growth and np.any(self.dynamics.process_noise(np.zeros(len(self.dynamics.labels)), 1.0) != 0.0):
            raise ValueError(
                "relinearise needs a deterministic process model (zero process noise, e.g. "
                "sigma_accel: 0): the batch re-solve has no process noise in it"
            )
        self.relinearise = float(growth)
        self.relinearise_from = int(first)
        self._batch: PassBatch | None = None
        self._next_solve = self.relinearise_from

    def initialise(self, x0: np.ndarray, P0: np.ndarray, t0: float) -> None:
        super().initialise(x0, P0, t0)
        self._batch = PassBatch(self.dynamics, self.x, self.P, self.t) if self.relinearise else None
        self._next_solve = self.relinearise_from

    def process(self, t: float, z: np.ndarray, R: np.ndarray, model: MeasurementModel):
        result = super().process(t, z, R, model)
        if self._batch is None or not result.accepted:
            return result
        self._batch.add(t, z, R, model)
        if len(self._batch) >= self._next_solve:
            self._next_solve = max(len(self._batch) + 1, math.ceil(len(self._batch) * self.relinearise))
            result.warnings.extend(self._resolve())
        return result

    def _resolve(self) -> list[str]:
        """Replace (x, P) by the batch solution, warm-started from the current estimate carried back to t0.

        Returns warnings (a failed solve keeps the recursive estimate)."""
        guess = self.dynamics.propagate(self.x, self._batch.t0 - self.t)
        try:
            x, P, _ = self._batch.solve(guess)
            P, repaired = ensure_pd(P)
        except (np.linalg.LinAlgError, FloatingPointError, ValueError) as err:
            return [f"{self.name}: batch re-linearisation failed ({err}); recursive estimate kept"]
        if not np.all(np.isfinite(x)):
            return [f"{self.name}: batch re-linearisation gave a non-finite state; recursive estimate kept"]
        self.x, self.P = x, P
        return (
            [f"{self.name}: covariance lost positive-definiteness in the batch re-linearisation; repaired"]
            if repaired
            else []
        )
