"""Posterior Cramér-Rao bound (PCRB) of a state-space estimation problem along a known true trajectory.

Tichavský, Muravchik and Nehorai, "Posterior Cramér-Rao bounds for discrete-time nonlinear filtering",
IEEE Trans. Signal Processing 46(5), 1998 (TMN): for x_{k+1} = f_k(x_k) + w_k, w_k ~ N(0, Q_k) and
z_k = h_k(x_k) + v_k, v_k ~ N(0, R_k), the information matrix J_k of x_k (the MSE of any estimator of x_k
from z_0..z_k satisfies E[(x̂ - x)(x̂ - x)^T] >= J_k^{-1}) obeys their recursion

    J_{k+1} = D22 - D21 (J_k + D11)^{-1} D12,
    D11 = E[F^T Q^{-1} F],  D12 = D21^T = -E[F^T] Q^{-1},  D22 = Q^{-1} + E[H^T R^{-1} H],

with F = df/dx and H = dh/dx. By the matrix inversion lemma this is (additive Gaussian noise)

    J_{k+1} = (Q_k + F_k J_k^{-1} F_k^T)^{-1} + H_{k+1}^T R_{k+1}^{-1} H_{k+1},          (1)

and with zero process noise (Q_k = 0: a deterministic truth, e.g. an orbit)

    J_{k+1} = F_k^{-T} J_k F_k^{-1} + H_{k+1}^T R_{k+1}^{-1} H_{k+1},                     (2)

i.e. the prior information J_0 propagated through the state-transition matrices plus the Fisher information
of every scan so far, each mapped to t_{k+1}. (2) holds for a singular J_k (a state part the prior leaves
unknown), (1) needs J_k invertible. For a linear-Gaussian model, J_k^{-1} is the Kalman filter's covariance.

Choice (stated): the expectations over the state are evaluated on the true trajectory (F and H at the true
state), the usual "PCRB along the truth"; for linear models it is exact. A step without a scan adds no
information (a missed detection, an invisible target or an off-cycle step): given the scans actually delivered,
this is the bound conditional on the detection sequence; its mean over Monte Carlo runs is the enumeration bound
for P_D < 1 (never below the information-reduction-factor bound, by Jensen's inequality).

No rclpy, no scenario: arrays and models (bench_models.models) only.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bench_models.models import DynamicsModel, MeasurementModel


def measurement_information(model: MeasurementModel, R: np.ndarray, x: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Fisher information of scans at the true states x (K, n) and ``times`` (K,): H^T R^{-1} H per scan (TMN's
    E[H^T R^{-1} H] on the truth), shape (K, n, n); the model's vectorised ``jacobian_series`` when it has one."""
    x, times = np.asarray(x, dtype=float), np.asarray(times, dtype=float)
    if hasattr(model, "jacobian_series"):
        H = np.asarray(model.jacobian_series(x, times), dtype=float)
    else:
        H = np.array([model.jacobian(xk, tk) for xk, tk in zip(x, times)], dtype=float).reshape(len(x), -1, x.shape[1])
    return np.swapaxes(H, 1, 2) @ (np.linalg.inv(np.asarray(R, dtype=float)) @ H)


def pcrb_recursion(J0: np.ndarray, transitions: np.ndarray, noises: np.ndarray, informations: np.ndarray) -> np.ndarray:
    """Information matrices J_0..J_{K-1} (K, n, n) from J_0 (its scan included) by eqs. (1)-(2):
    ``transitions[k]`` and ``noises[k]`` take step k to k+1 ((K-1, n, n) each), ``informations[k]`` is the scan
    information added at step k+1 ((K-1, n, n); zero for a step without scan). Eq. (2) (Q = 0) holds for a
    singular J; eq. (1) needs J_k invertible (ValueError otherwise)."""
    F, Q = np.asarray(transitions, dtype=float), np.asarray(noises, dtype=float)
    noiseless = ~np.any(Q.reshape(len(Q), -1), axis=1)
    Finv = np.linalg.inv(F)
    J = np.empty((len(F) + 1,) + np.shape(J0))
    J[0] = J0
    for k in range(len(F)):
        if noiseless[k]:
            Jk = Finv[k].T @ J[k] @ Finv[k]
        else:
            try:
                Jk = np.linalg.inv(Q[k] + F[k] @ np.linalg.inv(J[k]) @ F[k].T)
            except np.linalg.LinAlgError as err:
                raise ValueError(
                    "the PCRB with process noise needs an invertible prior information "
                    "(a state part the prior leaves unknown)"
                ) from err
        Jk = Jk + informations[k]
        J[k + 1] = 0.5 * (Jk + Jk.T)
    return J


def pcrb_along_truth(
    dynamics: DynamicsModel,
    times: np.ndarray,
    states: np.ndarray,
    scans: Sequence[Sequence[tuple[MeasurementModel, np.ndarray]]],
    J0: np.ndarray,
) -> np.ndarray:
    """Bound covariances J_k^{-1} (K, n, n) at ``times`` (K,) along the true ``states`` (K, n, in the
    dynamics' layout), with ``dynamics``' transition matrix (or, for a time-varying model, its
    ``transition_matrices(times, states)``) and process noise between consecutive times, and
    at each step k > 0 the information of every (model, R) of ``scans[k]`` (possibly none). ``J0`` is the
    information at times[0], its scans included (``scans[0]`` is not used). A bound that is not finite yet
    (a state part still unobserved) is NaN."""
    times, states = np.asarray(times, dtype=float), np.asarray(states, dtype=float)
    K, n = states.shape
    dts = np.diff(times)
    if hasattr(dynamics, "transition_matrices"):  # a time-varying model (bench_models.truth_dynamics)
        F = np.asarray(dynamics.transition_matrices(times, states), dtype=float)
    else:
        F = np.array([dynamics.transition_matrix(x, dt) for x, dt in zip(states[:-1], dts)]).reshape(K - 1, n, n)
    Q = np.array([dynamics.process_noise(x, dt) for x, dt in zip(states[:-1], dts)]).reshape(K - 1, n, n)
    info = np.zeros((K - 1, n, n))
    groups: dict[int, tuple[MeasurementModel, np.ndarray, list[int]]] = {}
    for k in range(1, K):
        for model, R in scans[k]:
            groups.setdefault(id(model), (model, R, []))[2].append(k)
    for model, R, rows in groups.values():  # each sensor's scans at once
        np.add.at(info, np.array(rows) - 1, measurement_information(model, R, states[rows], times[rows]))
    return information_to_covariance(pcrb_recursion(np.asarray(J0, dtype=float), F, Q, info))


def information_to_covariance(J: np.ndarray) -> np.ndarray:
    """J^{-1} per step (K, n, n), symmetrised; NaN where J is singular (no finite bound yet)."""
    P = np.full_like(J, np.nan)
    finite = np.linalg.cond(J) < 1e15
    if finite.any():
        Pk = np.linalg.inv(J[finite])
        P[finite] = 0.5 * (Pk + np.swapaxes(Pk, 1, 2))
    return P
