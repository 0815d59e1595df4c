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

from bench_engine.config import ScenarioError
from bench_engine.labels import ORBIT
from bench_engine.settings import NoKeys
from bench_eval.bounds import Bound, BoundSeries
from bench_eval.scoring import BagData, Estimates
from bench_studies.grace_velocity.metrics import BASELINE, range_rate_bound, range_rate_sd
from bench_studies.grace_velocity.pair_fit import PairFitParameters, pair_force_model
from orbit_sim.orbit_fit import information
from orbit_sim.truth import read_truth
from radar_sensor.sensor_types import read_sensors


def baseline_bound(data: BagData, sensors: tuple[str, str] = ("gnss1", "gnss2")) -> BoundSeries:
    """Bound (b) on the baseline [bx by bz bvx bvy bvz] at the truth steps of the fixes' span: P_1 + P_2, each
    satellite's Cramer-Rao bound mapped from its orbit's parameters (module docstring)."""
    cfg = data.scenario
    truth, gnss = read_truth(cfg).options, read_sensors(cfg)
    model = pair_force_model(cfg, PairFitParameters(second=sensors[1], zonal_degree=truth.zonal_degree, drag=True))
    labels = data.truth_labels
    steps = np.array(sorted(data.truth))
    t_all = np.array([data.truth[int(k)][0] for k in steps])
    P = []
    for sat, (name, ballistic) in enumerate(zip(sensors, truth.ballistic)):
        fix_steps = np.array(sorted(data.measurements[name]))
        t = np.array([data.truth[int(k)][0] for k in fix_steps])
        cols = [labels.index(f"{c}{sat + 1}") for c in ORBIT]
        fit = information(model, data.truth[int(fix_steps[0])][1][cols], ballistic, t, gnss[name].model.sigma_position)
        keep = (t_all >= t[0]) & (t_all <= t[-1])
        P.append(fit.states(t_all[keep])[1])
    return BoundSeries(steps[keep], t_all[keep], list(BASELINE), P[0] + P[1])


def dynamic_bound(data: BagData) -> tuple[np.ndarray, np.ndarray]:
    """Bound (b) on the range rate: (t (K,), its standard deviation's bound (K,)), at the truth's baseline."""
    series = baseline_bound(data)
    return series.t, range_rate_bound(data, series)


def _orbit_crb_check(cfg: dict, params: NoKeys) -> None:
    if read_truth(cfg).model != "pair_hifi":
        raise ScenarioError("'scoring.bounds' orbit_crb needs the pair_hifi truth (its force model is the bound's)")


ORBIT_CRB = Bound(run=lambda data, params: baseline_bound(data), check=_orbit_crb_check)
"""Bound (b) on the baseline, registered in tracking_bench.bounds (bench_eval.bounds scores every estimator's
baseline position and velocity against it)."""


def smoother_bound(est: Estimates, baseline: list[str]) -> np.ndarray:
    """Bound (a): the range-rate standard deviation of a smoother's own covariance (K,) along its estimates."""
    cols = [est.labels.index(c) for c in baseline]
    x, P = est.x[:, cols], est.P[:, cols][:, :, cols]
    return range_rate_sd(x[:, :3], x[:, 3:], P)
