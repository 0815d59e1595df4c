"""The bounds of the scenario's ``scoring.bounds`` (bench_eval.bounds) in the ground radar's coordinates.

The bound on h(x) (range, azimuth, elevation) is H P_bound H^T with H = dh/dx at the truth (the CRB of a
function of the state). At every scan from the bound's ``from_s`` on (after each run's first estimate), the
filter's estimate and the truth are mapped through the filter's radar model h (angle errors wrapped), and
pooled over runs and scans: ``radar.bounds.NAME.COMPONENT = {rmse, sqrt_bound, ratio}`` (range_m,
azimuth_mrad, elevation_mrad), ratio = √bound / RMSE (1 = at the bound).
"""

from __future__ import annotations

import numpy as np

from bench_eval.scoring import BagData, scoring_options
from orbit_sim.angles import wrapped_residual
from tracker_filters.builders import build_filter_stack

RADAR_UNITS = (("range_m", 1.0), ("azimuth_mrad", 1e3), ("elevation_mrad", 1e3))
"""Radar components (range, azimuth, elevation) in measurement order, with the factor from SI to the unit."""


def radar_errors_and_bound(
    data: BagData, filter_name: str, bound: str, from_s: float
) -> tuple[np.ndarray, np.ndarray] | None:
    """(squared errors, bound variances), each (K, 3), of the filter's estimates in its (first) radar's
    coordinates at the scans from ``from_s`` after its first estimate (None when there are none or the bound has
    other components)."""
    stack = build_filter_stack(data.scenario, filter_name)
    sensor_name = next(iter(stack.sensors))
    model, meas = stack.sensors[sensor_name].model, data.measurements.get(sensor_name, {})
    series, est = data.bounds[bound], data.estimates[filter_name]
    index = {int(k): i for i, k in enumerate(series.steps)}
    rows = [i for i, k in enumerate(est.steps) if int(k) in meas and int(k) in index and est.t[i] - est.t[0] >= from_s]
    if not rows or list(series.labels) != list(est.labels):
        return None
    steps, t = [int(est.steps[i]) for i in rows], est.t[rows]
    x_true = np.array([data.truth[k][1] for k in steps])
    err = wrapped_residual(model.h_series(est.x[rows], t), model.h_series(x_true, t), model.angle_indices)
    H = model.jacobian_series(x_true, t)
    P = series.P[[index[k] for k in steps]]
    return err**2, np.einsum("kij,kjl,kil->ki", H, P, H)


def add_radar_bounds(scored: dict, runs: list[BagData]) -> None:
    """Add ``radar.bounds`` (module docstring) to every filter block with a ``radar`` block, for every bound the
    runs carry (bench_eval.bounds.compute_bounds)."""
    if not runs or not runs[0].bounds:
        return
    bounds = scoring_options(runs[0].scenario).bounds
    for name, block in scored.items():
        having = [d for d in runs if name in d.estimates]
        if not block.get("radar") or not having:
            continue
        for bound in having[0].bounds:
            pairs = [radar_errors_and_bound(d, name, bound, bounds[bound].from_s) for d in having]
            if any(p is None for p in pairs):
                continue
            rmse = np.sqrt(np.mean(np.vstack([p[0] for p in pairs]), axis=0))
            root = np.sqrt(np.mean(np.vstack([p[1] for p in pairs]), axis=0))
            block["radar"].setdefault("bounds", {})[bound] = {
                key: {"rmse": float(r * scale), "sqrt_bound": float(b * scale), "ratio": float(b / r) if r else None}
                for (key, scale), r, b in zip(RADAR_UNITS, rmse, root)
            }
