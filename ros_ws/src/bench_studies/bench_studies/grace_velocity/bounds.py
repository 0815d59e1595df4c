"""Lower bounds on grace_velocity's range-rate residual against the truth (issue 19, section 1).

(b) Under the truth's deterministic dynamics each satellite's orbit is fixed by its state at the first fix and
its C_d A / m: the Cramer-Rao bound of these 7 parameters given the satellite's GNSS fixes is the inverse of
their Fisher information sum_k H_k' H_k / sigma^2 (H_k = d r(t_k) / d p at the true orbit, the truth's force
model: orbit_sim.orbit_fit.information). Mapped to the baseline (the satellites' fixes are independent:
P_b = P_1 + P_2) and to the range rate rho_dot = b . w / |b| (paper 002 eq. 27) by its gradient

    g = [(w - rho_dot b_hat) / |b|, b_hat],   var(rho_dot) >= g' P_b g.

(a) Under the white-jerk model with the filter's q the bound is the fixed-interval smoother's covariance (the
model is linear-Gaussian), the same gradient applied to the RTS estimate's covariance.
"""
from __future__ import annotations

import numpy as np

from bench_eval.offline import pair_force_model
from bench_eval.scoring import BagData, Estimates
from orbit_sim.orbit_fit import information

TRUTH_MODEL = {"zonal_degree": 6, "drag": True}
"""pair_hifi's force model as the fit's params (the scenario's truth.zonal_degree replaces the degree)."""


def range_rate_sd(b: np.ndarray, w: np.ndarray, P: np.ndarray) -> np.ndarray:
    """sqrt(g' P g) per row for baselines b, w (K, 3) and their covariance P (K, 6, 6) (module docstring)."""
    rng = np.linalg.norm(b, axis=1, keepdims=True)
    b_hat = b / rng
    rho_dot = np.sum(b_hat * w, axis=1, keepdims=True)
    g = np.hstack([(w - rho_dot * b_hat) / rng, b_hat])
    return np.sqrt(np.einsum("ki,kij,kj->k", g, P, g))


def dynamic_bound(data: BagData, sensors: tuple[str, str] = ("gnss1", "gnss2")) -> tuple[np.ndarray, np.ndarray]:
    """Bound (b): (t (K,), the range-rate standard deviation's bound (K,)) at the truth steps of the fixes' span."""
    cfg = data.scenario
    truth = cfg["truth"]
    params = {**TRUTH_MODEL, "zonal_degree": int(truth.get("zonal_degree", 6))}
    model = pair_force_model(cfg, params)
    labels = data.truth_labels
    steps = np.array(sorted(data.truth))
    t_all = np.array([data.truth[int(k)][0] for k in steps])
    states, P = [], []
    for sat, (name, ballistic) in enumerate(zip(sensors, truth["ballistic"])):
        fix_steps = np.array(sorted(data.measurements[name]))
        t = np.array([data.truth[int(k)][0] for k in fix_steps])
        cols = [labels.index(f"{c}{sat + 1}") for c in ("x", "y", "z", "vx", "vy", "vz")]
        x0 = data.truth[int(fix_steps[0])][1][cols]
        fit = information(model, x0, float(ballistic), t, float(cfg["sensors"][name]["sigma_position"]))
        keep = (t_all >= t[0]) & (t_all <= t[-1])
        x, cov = fit.states(t_all[keep])
        states.append(x)
        P.append(cov)
    b = states[1] - states[0]
    return t_all[keep], range_rate_sd(b[:, :3], b[:, 3:], P[0] + P[1])


def smoother_bound(est: Estimates, baseline: list[str]) -> np.ndarray:
    """Bound (a): the range-rate standard deviation of a smoother's own covariance (K,) along its estimates."""
    cols = [est.labels.index(c) for c in baseline]
    x, P = est.x[:, cols], est.P[:, cols][:, :, cols]
    return range_rate_sd(x[:, :3], x[:, 3:], P)
