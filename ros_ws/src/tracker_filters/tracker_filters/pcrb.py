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

from typing import Sequence

import numpy as np
from scipy.linalg import LinAlgError, lu_factor, lu_solve

from bench_models.models import DynamicsModel, MeasurementModel


def measurement_information(model: MeasurementModel, R: np.ndarray, x: np.ndarray, t: float) -> np.ndarray:
    """Fisher information of one scan at the true state: H^T R^{-1} H (TMN's E[H^T R^{-1} H] on the truth),
    shape (n, n)."""
    H = np.asarray(model.jacobian(np.asarray(x, dtype=float), t), dtype=float)
    return H.T @ np.linalg.solve(np.asarray(R, dtype=float), H)


def predict_information(J: np.ndarray, F: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """The information of x_{k+1} before its scan: eq. (2) when Q is zero, else eq. (1)'s first term."""
    if not np.any(Q):
        lu = lu_factor(F)
        Finv = lu_solve(lu, np.eye(len(F)))
        return Finv.T @ J @ Finv
    try:
        P = np.linalg.inv(J)
    except LinAlgError as err:
        raise ValueError("the PCRB with process noise needs an invertible prior information "
                         "(a state part the prior leaves unknown)") from err
    return np.linalg.inv(Q + F @ P @ F.T)


def pcrb_recursion(J0: np.ndarray, transitions: Sequence[np.ndarray], noises: Sequence[np.ndarray],
                   informations: Sequence[np.ndarray]) -> np.ndarray:
    """Information matrices J_0..J_{K-1} (K, n, n) from J_0 (its scan included) by eqs. (1)-(2):
    ``transitions[k]`` and ``noises[k]`` take step k to k+1 (K-1 of each), ``informations[k]`` is the scan
    information added at step k+1 (K-1 of them; a zero matrix for a step without scan)."""
    J = np.empty((len(transitions) + 1,) + np.shape(J0))
    J[0] = J0
    for k, (F, Q, info) in enumerate(zip(transitions, noises, informations)):
        Jk = predict_information(J[k], np.asarray(F, float), np.asarray(Q, float)) + info
        J[k + 1] = 0.5 * (Jk + Jk.T)
    return J


def pcrb_along_truth(dynamics: DynamicsModel, times: np.ndarray, states: np.ndarray,
                     scans: Sequence[Sequence[tuple[MeasurementModel, np.ndarray]]],
                     J0: np.ndarray) -> np.ndarray:
    """Bound covariances J_k^{-1} (K, n, n) at ``times`` (K,) along the true ``states`` (K, n, in the
    dynamics' layout), with ``dynamics``' transition matrix (or, for a time-varying model, its
    ``transition_matrices(times, states)``) and process noise between consecutive times, and
    at each step k > 0 the information of every (model, R) of ``scans[k]`` (possibly none). ``J0`` is the
    information at times[0], its scans included (``scans[0]`` is not used). A bound that is not finite yet
    (a state part still unobserved) is NaN."""
    times, states = np.asarray(times, dtype=float), np.asarray(states, dtype=float)
    n = states.shape[1]
    if hasattr(dynamics, "transition_matrices"):  # a time-varying model (bench_models.truth_dynamics)
        F = dynamics.transition_matrices(times, states)
    else:
        F = [dynamics.transition_matrix(x, dt) for x, dt in zip(states[:-1], np.diff(times))]
    Q = [dynamics.process_noise(x, dt) for x, dt in zip(states[:-1], np.diff(times))]
    info = [sum((measurement_information(m, R, x, t) for m, R in step), np.zeros((n, n)))
            for x, t, step in zip(states[1:], times[1:], scans[1:])]
    return information_to_covariance(pcrb_recursion(np.asarray(J0, dtype=float), F, Q, info))


def information_to_covariance(J: np.ndarray) -> np.ndarray:
    """J^{-1} per step (K, n, n), symmetrised; NaN where J is singular (no finite bound yet)."""
    P = np.full_like(J, np.nan)
    for k, Jk in enumerate(J):
        if np.linalg.cond(Jk) < 1e15:
            Pk = np.linalg.inv(Jk)
            P[k] = 0.5 * (Pk + Pk.T)
    return P
