"""Particle filters, vectorised over the cloud (a batch (N, n) through ``propagate`` and ``h``).

- ``SIRParticleFilter`` ("sir"): paper 001 §3 exactly — transition-prior proposal, log-weights updated by the
  likelihood, multinomial resampling when N_eff = 1/Σw² < N_th = 2N/3, weighted mean and spread as output.
- ``RegularisedParticleFilter`` ("pf"): the bench's default. Each particle is the centre of a Gaussian kernel
  N(c_i, Q + h²C) (regularised PF, Musso, Oudjane & Le Gland 2001, with the Liu & West 2001 shrinkage
  c_i = a·x_i + (1 − a)·x̄, a = √(1 − h²), which keeps the cloud's mean and covariance C). The importance
  density is the linearised optimal proposal of each kernel given z (Doucet, Godsill & Andrieu 2000): one
  gain K from the Jacobian at the cloud mean, the per-particle mean refined by Gauss–Newton passes on the
  full nonlinear h while a probe of the cloud says they still move it, and exact importance weights
  p(z|x)·N(x; c_i, S)/N(x; m_i, Σ). It stays healthy when the likelihood is far narrower than the cloud
  (paper 001: 2 cm range against a 50 m prior), where the SIR collapses onto a handful of particles.

Both keep normalised log-weights (logsumexp), report ``diagnostics()["n_eff"]`` (before resampling), and
recover from a likelihood that vanishes for every particle (overflow, NaN) by re-drawing the cloud from the
predicted mean and covariance, with a warning, instead of producing a NaN estimate.

Layout: the cloud is held component-first, ``_cols`` of shape (n, N) with one particle per column, and every
per-particle operation is written on such (dim, N) arrays; ``particles`` is its (N, n) transpose, the batch
layout of the model protocol. With numpy, broadcasting along long contiguous rows of N numbers is much
cheaper than along rows of n = 6, and ``A @ Y`` than ``X @ A.T`` with a transposed 6×6 A; with N = 10 000
this layout is what keeps a step of the "pf" within its budget (scripts/bench_formation_filters.py).
"""

from __future__ import annotations

from abc import abstractmethod

import numpy as np
from scipy.linalg import lapack
from scipy.special import logsumexp

from bench_models.models import DynamicsModel, MeasurementModel
from tracker_filters.covariance import ensure_pd
from tracker_filters.filter_base import Filter, StepResult
from tracker_filters.resampling import RESAMPLERS

PROBE_SIZE = 256
"""Particles (an evenly strided subset) on which the "pf" tests whether another Gauss–Newton pass is needed."""
PASS_TOLERANCE = 0.1
"""Another pass runs while it would move a probed proposal mean by more than this many proposal σ."""


def sampling_factor(M: np.ndarray) -> np.ndarray:
    """A matrix L with L Lᵀ = M for a symmetric positive semi-definite M (eigen-decomposition if singular)."""
    try:
        return np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(0.5 * (M + M.T))
        return V * np.sqrt(np.clip(w, 0.0, None))


def columns(X: np.ndarray) -> np.ndarray:
    """The (N, n) batch X as a C-contiguous (n, N) array, one state per column (no copy if X.T already is)."""
    return np.ascontiguousarray(np.asarray(X, dtype=float).T)


def column_sq_norms(W: np.ndarray) -> np.ndarray:
    """|w_j|² for each column of W (d, N)."""
    return np.einsum("ij,ij->j", W, W)


def mahalanobis_sq(D: np.ndarray, L: np.ndarray, plus: np.ndarray | None = None) -> np.ndarray:
    """Column-wise |L⁻¹ d_j|² (or |L⁻¹ d_j + p_j|² with ``plus`` P) for D (d, N), lower Cholesky factor L.

    Multiplies by the explicit d×d inverse from LAPACK dtrtri: scipy's solve_triangular carries a large
    per-call overhead on a 6×6 system and, with N = 10 000 right-hand sides or a multi-threaded OpenBLAS
    under load, can take longer than the whole per-step budget.
    """
    L_inv, info = lapack.dtrtri(L, lower=1)
    if info != 0:
        raise np.linalg.LinAlgError(f"triangular inverse failed (LAPACK info={info})")
    W = L_inv @ D
    if plus is not None:
        W += plus
    return column_sq_norms(W)


def weighted_moments(Y: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted mean Σ w_j y_j and spread Σ w_j (y_j − ȳ)(y_j − ȳ)ᵀ of the columns of Y (paper 001 step 8)."""
    mean = Y @ w
    D = Y - mean[:, None]
    D *= np.sqrt(w)
    return mean, D @ D.T


def innovation_nis(nu: np.ndarray, w: np.ndarray, extra_cov: np.ndarray) -> float:
    """NIS of the mean innovation ν̄ = Σ w_j ν_j (columns of ν) against their weighted spread + ``extra_cov``."""
    nu_bar, spread = weighted_moments(nu, w)
    S = spread + extra_cov
    return float(nu_bar @ np.linalg.solve(S, nu_bar))


def silverman_bandwidth(n_particles: int, dim: int) -> float:
    """Optimal Gaussian-kernel width h = (4 / (N (n + 2)))^(1 / (n + 4)) in units of the cloud spread."""
    return (4.0 / (n_particles * (dim + 2.0))) ** (1.0 / (dim + 4.0))


class ParticleFilterBase(Filter):
    """Cloud bookkeeping shared by the particle filters: sampling, weights, resampling, recovery.

    ``threshold`` is N_th / N: the cloud is resampled when N_eff < threshold·N.
    """

    def __init__(
        self,
        dynamics: DynamicsModel,
        n_particles: int = 1000,
        resampling: str = "multinomial",
        threshold: float = 2.0 / 3.0,
        seed: int | None = None,
    ) -> None:
        super().__init__(dynamics)
        if int(n_particles) != n_particles or n_particles < 2:
            raise ValueError(f"{self.name}: n_particles must be an integer >= 2, got {n_particles!r}")
        if resampling not in RESAMPLERS:
            raise ValueError(f"{self.name}: resampling must be one of {sorted(RESAMPLERS)}, got {resampling!r}")
        if not 0.0 < threshold <= 1.0:
            raise ValueError(f"{self.name}: threshold must be in (0, 1], got {threshold!r}")
        self.n_particles = int(n_particles)
        self.resampling = resampling
        self.threshold = float(threshold)
        self._resample = RESAMPLERS[resampling]
        self._rng = np.random.default_rng(seed)
        self._cols: np.ndarray | None = None
        self._logw: np.ndarray | None = None
        self._n_eff = float(self.n_particles)
        self._resampled = False
        self._cloud_mean: np.ndarray | None = None
        self._cloud_cov: np.ndarray | None = None

    @property
    def particles(self) -> np.ndarray | None:
        """The cloud (N, n), one particle per row (a view: read, don't write)."""
        return None if self._cols is None else self._cols.T

    @property
    def weights(self) -> np.ndarray:
        """Normalised particle weights (N,)."""
        return np.exp(self._logw)

    def initialise(self, x0: np.ndarray, P0: np.ndarray, t0: float) -> None:
        """Start from mean x0 and covariance P0: N particles drawn from N(x0, P0), equal weights."""
        super().initialise(x0, P0, t0)
        self._draw_cloud(self.x, self.P)

    def diagnostics(self) -> dict[str, float]:
        """``n_eff``: 1/Σw² after the last update, before resampling; ``resampled``: 1 if it resampled."""
        return {"n_eff": self._n_eff, "resampled": float(self._resampled)}

    def process(self, t: float, z: np.ndarray, R: np.ndarray, model: MeasurementModel) -> StepResult:
        """``Filter.process``; a rejected or failed step also leaves the particle cloud untouched."""
        saved = self._cloud_state()
        result = super().process(t, z, R, model)
        if not result.accepted:
            self._restore_cloud(saved)
        return result

    def _cloud_state(self) -> tuple:
        return self._cols, self._logw, self._n_eff, self._resampled, self._cloud_mean, self._cloud_cov

    def _restore_cloud(self, state: tuple) -> None:
        (self._cols, self._logw, self._n_eff, self._resampled, self._cloud_mean, self._cloud_cov) = state

    def _draw_cloud(self, mean: np.ndarray, cov: np.ndarray) -> None:
        """Replace the cloud by N equally weighted draws from N(mean, cov); N_eff = N."""
        noise = self._rng.standard_normal((mean.size, self.n_particles))
        self._cols = sampling_factor(cov) @ noise + mean[:, None]
        self._logw = np.full(self.n_particles, -np.log(self.n_particles))
        self._n_eff = float(self.n_particles)
        self._cloud_mean, self._cloud_cov = weighted_moments(self._cols, self.weights)

    def _drop_nonfinite(self, when: str) -> None:
        """Give zero weight to particles with non-finite components (their values are replaced by 0)."""
        with np.errstate(invalid="ignore", over="ignore"):
            if np.isfinite(np.sum(self._cols)):
                return
        bad = ~np.all(np.isfinite(self._cols), axis=0)
        if not np.any(bad):
            return
        if np.all(bad):
            raise FloatingPointError(f"{self.name}: every particle became non-finite {when}")
        self._cols = np.where(bad, 0.0, self._cols)
        logw = np.where(bad, -np.inf, self._logw)
        self._logw = logw - logsumexp(logw)
        self._warnings.append(f"{self.name}: {int(bad.sum())} particles non-finite {when}; weights set to 0")

    def _set_moments(self, extra_cov: np.ndarray | None = None) -> None:
        """x, P = weighted mean and spread of the cloud (+ ``extra_cov``); the cloud's own moments are kept."""
        self._cloud_mean, self._cloud_cov = weighted_moments(self._cols, self.weights)
        self.x = self._cloud_mean
        self.P = self._cloud_cov if extra_cov is None else self._cloud_cov + extra_cov

    def _absorb(self, loglik: np.ndarray) -> None:
        """w_i ∝ w_i·exp(loglik_i) in log space; N_eff; resample below the threshold (paper 001 steps 3–6).

        If no particle keeps a finite positive weight, the cloud is re-drawn from the current (predicted)
        x, P and the measurement is not used; a warning says so.
        """
        logw = self._logw + np.where(np.isnan(loglik), -np.inf, loglik)
        top = np.max(logw)
        self._resampled = False
        if not np.isfinite(top):
            self._warnings.append(
                f"{self.name}: every particle weight vanished (likelihood underflow/overflow or NaN) at "
                f"t={self.t} s; cloud re-drawn from the predicted mean and covariance, measurement not used"
            )
            self._draw_cloud(self.x, self.P)
            return
        logw -= top + np.log(np.sum(np.exp(logw - top)))
        w = np.exp(logw)
        self._n_eff = float(1.0 / (w @ w))
        if self._n_eff < self.threshold * self.n_particles:
            self._cols = np.take(self._cols, self._resample(w, self._rng), axis=1)
            logw = np.full(self.n_particles, -np.log(self.n_particles))
            self._resampled = True
        self._logw = logw

    @staticmethod
    def _measurement_loglik(nu: np.ndarray, L_R: np.ndarray) -> np.ndarray:
        """log N(ν_j; 0, R) up to a constant, for innovations ν (d, N) (columns) and chol(R) = L_R."""
        with np.errstate(over="ignore", invalid="ignore"):
            return -0.5 * mahalanobis_sq(nu, L_R)

    @abstractmethod
    def _predict(self, dt: float) -> None:
        """Propagate the cloud by dt seconds and refresh x, P."""

    @abstractmethod
    def _update(self, z: np.ndarray, R: np.ndarray, model: MeasurementModel) -> float:
        """Weight (and move) the cloud with z; refresh x, P; return the NIS."""


class SIRParticleFilter(ParticleFilterBase):
    """Sequential importance resampling with the transition prior as proposal (paper 001 §3, steps 1–8)."""

    name = "sir"

    def _predict(self, dt: float) -> None:
        """Step 2: x_i ~ p(x_k | x_i): propagate each particle and add a draw of N(0, Q(dt))."""
        Q = self.dynamics.process_noise(self.x, dt)
        noise = sampling_factor(Q) @ self._rng.standard_normal(self._cols.shape)
        noise += columns(self.dynamics.propagate(self.particles, dt))
        self._cols = noise
        self._drop_nonfinite("after propagation")
        self._set_moments()

    def _update(self, z: np.ndarray, R: np.ndarray, model: MeasurementModel) -> float:
        """Steps 3–6: w_i ∝ w_i·p(z | x_i), N_eff, multinomial resampling; step 8: moments."""
        with np.errstate(invalid="ignore", over="ignore"):
            nu = columns(model.residual(z, model.h(self.particles, self.t)))
        nis = self._nis(nu, R)
        self._absorb(self._measurement_loglik(nu, np.linalg.cholesky(R)))
        self._set_moments()
        return nis

    def _nis(self, nu: np.ndarray, extra_cov: np.ndarray) -> float:
        """Predicted-measurement NIS (``innovation_nis``) over particles with finite ν and non-zero weight."""
        usable = np.all(np.isfinite(nu), axis=0) & np.isfinite(self._logw)
        w = self.weights[usable]
        if not np.sum(w) > 0.0:
            return float("inf")
        with np.errstate(over="ignore", invalid="ignore"):
            return innovation_nis(nu[:, usable], w / np.sum(w), extra_cov)


class RegularisedParticleFilter(ParticleFilterBase):
    """Regularised particle filter with a linearised optimal proposal (module docstring).

    ``bandwidth`` scales the kernel width h (1 = Silverman's optimum for N and n). The proposal means start
    from h linearised at the cloud mean (no per-particle h evaluation); ``iterations`` is the maximum number
    of Gauss–Newton passes on the nonlinear h that follow, each run only while it would move the probed
    means by > PASS_TOLERANCE σ. On paper 001's set-up the probe asks for one pass at the first update
    (50 m cloud) and none afterwards, so a steady-state step evaluates h once per particle. Starting the
    passes from h(c_i) instead, with H at the mean, left N_eff ≈ 5–25 of 10 000 at that first update: the
    proposal means all land near the measured point, close to the cloud mean, where the mean's
    linearisation is accurate. Process noise is carried as a pending covariance Q_pend (propagated with the
    transition matrix) until the next update, where it becomes part of each particle's kernel.
    """

    name = "pf"

    def __init__(
        self,
        dynamics: DynamicsModel,
        n_particles: int = 1000,
        resampling: str = "systematic",
        threshold: float = 2.0 / 3.0,
        seed: int | None = None,
        bandwidth: float = 1.0,
        iterations: int = 3,
    ) -> None:
        super().__init__(dynamics, n_particles, resampling, threshold, seed)
        n = len(dynamics.labels)
        h = bandwidth * silverman_bandwidth(self.n_particles, n)
        if not 0.0 < h < 1.0:
            raise ValueError(f"pf: bandwidth must give a kernel width h in (0, 1), got h={h!r}")
        if int(iterations) != iterations or iterations < 0:
            raise ValueError(f"pf: iterations must be an integer >= 0, got {iterations!r}")
        self.bandwidth = float(bandwidth)
        self.iterations = int(iterations)
        self._h2 = h * h
        self._Q_pend = np.zeros((n, n))
        self._passes = 0

    def diagnostics(self) -> dict[str, float]:
        """Base diagnostics plus ``gn_passes``: nonlinear Gauss–Newton passes the last update ran."""
        return {**super().diagnostics(), "gn_passes": float(self._passes)}

    def initialise(self, x0: np.ndarray, P0: np.ndarray, t0: float) -> None:
        super().initialise(x0, P0, t0)
        self._Q_pend = np.zeros_like(self.P)

    def _cloud_state(self) -> tuple:
        return super()._cloud_state() + (self._Q_pend,)

    def _restore_cloud(self, state: tuple) -> None:
        super()._restore_cloud(state[:-1])
        self._Q_pend = state[-1]

    def _predict(self, dt: float) -> None:
        """Propagate the kernel centres; Q_pend ← Φ Q_pend Φᵀ + Q(dt); P = cloud spread + Q_pend."""
        Phi = self.dynamics.transition_matrix(self.x, dt)
        Q = self.dynamics.process_noise(self.x, dt)
        self._cols = columns(self.dynamics.propagate(self.particles, dt))
        self._drop_nonfinite("after propagation")
        self._Q_pend = Phi @ self._Q_pend @ Phi.T + Q
        self._set_moments(self._Q_pend)

    def _update(self, z: np.ndarray, R: np.ndarray, model: MeasurementModel) -> float:
        """Draw each particle from its kernel's linearised posterior and weight it exactly.

        Columns: D = X − x̄, kernel centres c = x̄ + a·D, r_c = z − h_L(c) = ν̄ − a·H D with the linearisation
        h_L(x) = h(x̄) + H (x − x̄) and ν̄ = z ⊖ h(x̄); linearised posterior means m = c + K r_c; draws
        x = m' + L_Σ ε, ε ~ N(0, I), m' = m refined by ``_proposal_means``. Since
        N(z; h_L(x), R)·N(x; c, S) = N(z; h_L(c), P_zz)·N(x; m, Σ), the exact weight p(z|x)·N(x; c, S)/N(x; m', Σ)
        is, in logs and up to a constant,
        −|z ⊖ h(x)|²_R/2 + |z − h_L(x)|²_R/2 − |r_c|²_Pzz/2 + (|ε|² − |ε + L_Σ⁻¹(m' − m)|²)/2,
        the last term 0 when no Gauss–Newton pass ran: 3-row quadratic forms instead of 6-row ones.
        """
        x_bar, C = self._cloud_mean, self._cloud_cov
        a = np.sqrt(1.0 - self._h2)
        S, _ = ensure_pd(self._Q_pend + self._h2 * C)
        H = model.jacobian(x_bar, self.t)
        P_zz = H @ S @ H.T + R
        K = np.linalg.solve(P_zz, H @ S).T
        L_sigma = np.linalg.cholesky(ensure_pd(S - K @ P_zz @ K.T)[0])
        with np.errstate(invalid="ignore", over="ignore"):
            nu_bar = model.residual(z, model.h(x_bar, self.t))
            nis = float(nu_bar @ np.linalg.solve(H @ (C + self._Q_pend) @ H.T + R, nu_bar))
            D = self._cols - x_bar[:, None]
            centres = a * D
            centres += x_bar[:, None]
            r_c = H @ D
            r_c *= -a
            r_c += nu_bar[:, None]
            linear = K @ r_c
            linear += centres
            means = self._proposal_means(centres, linear, z, model, H, K, L_sigma)
            eps = self._rng.standard_normal((x_bar.size, self.n_particles))
            X = L_sigma @ eps
            X += means
            r_lin = H @ X
            np.subtract((nu_bar + H @ x_bar)[:, None], r_lin, out=r_lin)
            nu = columns(model.residual(z, model.h(X.T, self.t)))
            L_R = np.linalg.cholesky(R)
            loglik = mahalanobis_sq(r_lin, L_R)
            loglik -= mahalanobis_sq(nu, L_R)
            loglik -= mahalanobis_sq(r_c, np.linalg.cholesky(P_zz))
            if self._passes:
                loglik += column_sq_norms(eps) - mahalanobis_sq(means - linear, L_sigma, plus=eps)
            loglik *= 0.5
            if not np.isfinite(np.sum(X)):
                finite = np.all(np.isfinite(X), axis=0)
                X = np.where(finite, X, 0.0)
                loglik = np.where(finite, loglik, -np.inf)
        self._cols = X
        self._Q_pend = np.zeros_like(self._Q_pend)
        self._absorb(loglik)
        self._set_moments()
        return nis

    def _proposal_means(
        self,
        centres: np.ndarray,
        means: np.ndarray,
        z: np.ndarray,
        model: MeasurementModel,
        H: np.ndarray,
        K: np.ndarray,
        L_sigma: np.ndarray,
    ) -> np.ndarray:
        """Gauss–Newton passes m ← c + K (z − h(m) + H (m − c)) with the shared H, K (iterated EKF form).

        Each further pass is first tried on an evenly strided probe of PROBE_SIZE particles (columns) and
        applied to the whole cloud only if it would move a probed mean by more than PASS_TOLERANCE proposal σ.
        """
        probe = slice(None, None, max(1, self.n_particles // PROBE_SIZE))
        self._passes = 0
        for _ in range(self.iterations):
            step = self._gauss_newton(centres[:, probe], means[:, probe], z, model, H, K) - means[:, probe]
            if np.max(mahalanobis_sq(step, L_sigma)) <= PASS_TOLERANCE**2:
                break
            means = self._gauss_newton(centres, means, z, model, H, K)
            self._passes += 1
        return means

    def _gauss_newton(
        self,
        centres: np.ndarray,
        means: np.ndarray,
        z: np.ndarray,
        model: MeasurementModel,
        H: np.ndarray,
        K: np.ndarray,
    ) -> np.ndarray:
        """One pass on columns: c + K (z − h(m) + H (m − c))."""
        nu = columns(model.residual(z, model.h(means.T, self.t)))
        return centres + K @ (nu + H @ (means - centres))
