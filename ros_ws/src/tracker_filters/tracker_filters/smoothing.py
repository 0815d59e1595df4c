"""Fixed-interval Rauch-Tung-Striebel smoothing: a pure function over a filter's recorded output.

Given the filtered means x_k|k and covariances P_k|k of a linear(ised) Gaussian filter and the transitions
F_k, Q_k from step k to k+1, the smoothed estimates are (Rauch, Tung & Striebel 1965; Bar-Shalom, Li &
Kirubarajan, "Estimation with Applications to Tracking and Navigation", 2001, eqs. 8.6.1-14..16):

    P_k+1|k = F_k P_k|k F_k' + Q_k
    C_k     = P_k|k F_k' P_k+1|k^-1
    x_k|N   = x_k|k + C_k (x_k+1|N - F_k x_k|k)
    P_k|N   = P_k|k + C_k (P_k+1|N - P_k+1|k) C_k'

``smooth_estimates`` takes the transitions from a filter's dynamics model between consecutive estimates (the
offline ``rts`` estimator, bench_eval.offline, and the in-graph fixed-lag smoother, fixed_lag.py).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from bench_models.models import DynamicsModel


def smooth_estimates(
    dynamics: DynamicsModel, dts: np.ndarray, xs: np.ndarray, Ps: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """RTS-smoothed means (K, n) and covariances (K, n, n) of a filter's estimates ``xs`` (K, n), ``Ps``
    (K, n, n), with the transitions F_k = ``dynamics.transition_matrix(x_k|k, dt_k)`` and Q_k =
    ``dynamics.process_noise(x_k|k, dt_k)`` over ``dts`` (K - 1,), the seconds from each estimate to the next
    (the callers' own differences: float seconds, or integer nanoseconds × 1e-9)."""
    Fs = [dynamics.transition_matrix(x, dt) for x, dt in zip(xs, dts)]
    Qs = [dynamics.process_noise(x, dt) for x, dt in zip(xs, dts)]
    return rts_smoother(xs, Ps, np.array(Fs), np.array(Qs))


def rts_smoother(xs: np.ndarray, Ps: np.ndarray, Fs: np.ndarray, Qs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Smoothed means (K, n) and covariances (K, n, n) from filtered ``xs`` (K, n), ``Ps`` (K, n, n) and the
    transitions ``Fs``, ``Qs`` (K - 1, n, n) from each step to the next."""
    xs, Ps = np.asarray(xs, dtype=float), np.asarray(Ps, dtype=float)
    Fs, Qs = np.asarray(Fs, dtype=float), np.asarray(Qs, dtype=float)
    if len(Fs) != len(xs) - 1 or len(Qs) != len(xs) - 1:
        raise ValueError(f"need {len(xs) - 1} transitions for {len(xs)} estimates, got {len(Fs)} and {len(Qs)}")
    x_s, P_s = xs.copy(), Ps.copy()
    for k in range(len(xs) - 2, -1, -1):
        x_s[k], P_s[k] = rts_step(xs[k], Ps[k], rts_gain(xs[k], Ps[k], Fs[k], Qs[k]), x_s[k + 1], P_s[k + 1])
    return x_s, P_s


def rts_gain(x: np.ndarray, P: np.ndarray, F: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, ...]:
    """(F_k x_k|k, P_k+1|k, C_k) of one step (module docstring): everything the backward pass needs from the
    filtered estimate k and its transition, none of it from later estimates (the fixed-lag smoother computes it
    once per estimate and uses it in every window)."""
    P_pred = F @ P @ F.T + Q
    C = cho_solve(cho_factor(P_pred), F @ P).T  # P_k|k F' P_pred^-1 (P_pred symmetric)
    return F @ x, P_pred, C


def rts_step(
    x: np.ndarray, P: np.ndarray, gain: tuple[np.ndarray, ...], x_next: np.ndarray, P_next: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(x_k|N, P_k|N) from the filtered x_k|k, P_k|k, the step's :func:`rts_gain` and the smoothed k+1."""
    Fx, P_pred, C = gain
    P_s = P + C @ (P_next - P_pred) @ C.T
    return x + C @ (x_next - Fx), 0.5 * (P_s + P_s.T)
