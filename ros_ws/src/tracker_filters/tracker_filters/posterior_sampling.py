"""Reference posterior of a pass by adaptive importance sampling: what a consistent estimate must report.

Not a filter: a yardstick for the filters' consistency (scripts/leo_posterior_study.py). With a
deterministic process model every state is a function of the state x0 at the first scan's time t0, so the
exact posterior of x0 given the first-scan prior N(m0, P0) and every scan since is

    p(x0 | Z) ~ exp(-J(x0) / 2),   J(x0) = |W0 (x0 - m0)|^2 + sum_j |W_j (z_j - h_j(phi(x0, t_j)))|^2,

the cost of relinearisation.PassBatch evaluated without any linearisation (angles wrapped). The state at the
last scan is x_k = phi(x0, t_k), so the posterior mean and covariance of x_k are weighted moments of
propagated samples of x0.

Sampler. Importance sampling from a multivariate Student-t proposal (``dof`` degrees of freedom, scale
``scale`` times a covariance C), weights w_i ~ exp(-J(x0_i) / 2) / q(x0_i), normalised. The proposal
starts at the Gauss-Newton MAP with the Laplace covariance Lambda^-1 and is moved to the weighted mean and
covariance of x0 after each iteration with enough effective samples (population Monte Carlo, Cappe,
Guillin, Marin & Robert 2004); the last iteration's weights give the moments. Its effective sample size 1 / sum w_i^2
tells how well the
proposal covers the posterior: the moments are trustworthy when it is in the hundreds or more.

Cost: every iteration propagates ``n_samples`` states through every scan with ``dynamics.propagate`` on
(M, n) batches and evaluates ``model.h`` on them: the cost grows as M x (number of scans).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tracker_filters.kf import cholesky_lower, cholesky_solve
from tracker_filters.relinearisation import PassBatch

MIN_ADAPT_ESS = 10
"""The proposal moves to an iteration's weighted moments only if its effective sample size is at least this
many per state dimension; otherwise the next iteration draws again from the same proposal."""


@dataclass
class Posterior:
    """Importance-sampled posterior moments of the state at the last scan."""

    mean: np.ndarray
    covariance: np.ndarray
    ess: float
    """Effective sample size of the last iteration's weights."""
    mean0: np.ndarray
    """Posterior mean of x0 (at the first scan's time)."""
    covariance0: np.ndarray


def batch_cost(batch: PassBatch, X0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """J(x0) (M,) of samples X0 (M, n) at t0, and the samples propagated to the last scan (M, n)."""
    prior = (X0 - batch.m0) @ batch.W0.T
    cost = np.einsum("ij,ij->i", prior, prior)
    X, t_prev = np.array(X0, dtype=float), batch.t0
    for s in batch.scans:
        dt = s.t - t_prev
        if dt != 0.0:
            X = batch.dynamics.propagate(X, dt)
            t_prev = s.t
        r = s.model.residual(s.z, s.model.h(X, s.t)) @ s.W.T
        cost += np.einsum("ij,ij->i", r, r)
    return cost, X


def weighted_moments(X: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean (n,) and covariance (n, n) of rows X (M, n) with normalised weights w (M,)."""
    mean = w @ X
    dev = X - mean
    cov = (dev * w[:, None]).T @ dev
    return mean, 0.5 * (cov + cov.T)


def importance_sample(
    batch: PassBatch,
    mean: np.ndarray,
    cov: np.ndarray,
    n_samples: int,
    rng: np.random.Generator,
    dof: float = 5.0,
    scale: float = 2.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One importance-sampling pass from t_dof(mean, scale^2 cov): (X0 (M, n), X_last (M, n), weights (M,))."""
    n = mean.shape[0]
    g = rng.standard_normal((n_samples, n))
    stretch = np.sqrt(dof / rng.chisquare(dof, n_samples))
    X0 = mean + scale * (g @ cholesky_lower(cov).T) * stretch[:, None]
    d2 = np.einsum("ij,ij->i", g, g) * stretch**2  # Mahalanobis distance^2 in the proposal's metric
    cost, X = batch_cost(batch, X0)
    log_w = -0.5 * cost + 0.5 * (dof + n) * np.log1p(d2 / dof)
    w = np.exp(log_w - log_w.max())
    return X0, X, w / w.sum()


def adaptive_posterior(
    batch: PassBatch,
    guess: np.ndarray,
    n_samples: int,
    iterations: int,
    rng: np.random.Generator,
    dof: float = 5.0,
    scale: float = 2.0,
) -> Posterior:
    """Posterior moments at the last scan: Gauss-Newton MAP from ``guess`` (a state at t0), then
    ``iterations`` adaptive importance-sampling passes (module docstring)."""
    if n_samples < 10 * len(guess) or iterations < 1:
        raise ValueError(f"need n_samples >= {10 * len(guess)} and iterations >= 1, got {n_samples} and {iterations}")
    best, last_step, _ = batch.minimise(guess)
    mean0 = best.x0 + last_step
    cov0 = cholesky_solve(cholesky_lower(best.info), np.eye(len(mean0)))
    for _ in range(iterations):
        X0, X, w = importance_sample(batch, mean0, cov0, n_samples, rng, dof, scale)
        ess = float(1.0 / np.sum(w * w))
        if ess >= MIN_ADAPT_ESS * len(mean0):  # fewer effective samples cannot estimate a covariance
            mean0, cov0 = weighted_moments(X0, w)
    mean, cov = weighted_moments(X, w)
    return Posterior(mean, cov, ess, *weighted_moments(X0, w))
