"""The bounds of the scenario's ``scoring.bounds`` (bench_eval.bounds) in the ground radar's coordinates.

The bound on h(x) (range, azimuth, elevation) is H P_bound H^T with H = dh/dx at the truth (the CRB of a
function of the state), at the same scans as the filter's radar-coordinate RMSE (leo_radar/metrics.py:
radar_samples), pooled over the runs and scans like it: ``radar.bounds.NAME.{range_m, azimuth_mrad,
elevation_mrad}`` = sqrt(mean of the diagonal), and ``radar.efficiency.NAME`` = that / the filter's RMSE.
"""
from __future__ import annotations

import numpy as np

from bench_eval import metrics
from bench_eval.scoring import BagData


def radar_bound_variances(data: BagData, filter_name: str, bound: str) -> np.ndarray | None:
    """Diagonal of H P H^T (K, 3) of the run's bound ``bound`` in the filter's (first) radar's coordinates, at
    every estimate step with a recorded scan (None when there is none or the bound has other components)."""
    from tracker_filters.builders import build_filter_stack
    stack = build_filter_stack(data.scenario, filter_name)
    sensor_name = next(iter(stack.sensors))
    model, meas = stack.sensors[sensor_name].model, data.measurements.get(sensor_name, {})
    series, est = data.bounds[bound], data.estimates[filter_name]
    index = {int(k): i for i, k in enumerate(series.steps)}
    steps = [int(k) for k in est.steps if int(k) in meas and int(k) in index]
    if not steps or list(series.labels) != list(est.labels):
        return None
    H = [model.jacobian(data.truth[k][1], data.truth[k][0]) for k in steps]
    return np.array([np.diag(h @ series.P[index[k]] @ h.T) for h, k in zip(H, steps)])


def add_radar_bounds(scored: dict, runs: list[BagData]) -> None:
    """Add ``radar.bounds`` and ``radar.efficiency`` (module docstring) to every filter block with a ``radar``
    block, for every bound the runs carry (bench_eval.bounds.compute_bounds)."""
    for name, block in scored.items():
        radar = block.get("radar")
        having = [d for d in runs if name in d.estimates]
        if not radar or not having:
            continue
        for bound in having[0].bounds:
            var = [radar_bound_variances(d, name, bound) for d in having]
            if any(v is None for v in var):
                continue
            root = np.sqrt(np.nanmean(np.vstack(var), axis=0))
            values = {key: float(v * scale) for (key, scale), v in zip(metrics.RADAR_UNITS, root)}
            radar.setdefault("bounds", {})[bound] = values
            radar.setdefault("efficiency", {})[bound] = {
                key: b / radar["filter"][key] if radar["filter"][key] else None for key, b in values.items()}
