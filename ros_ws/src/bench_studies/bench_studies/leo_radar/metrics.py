"""The leo_radar metric family ``radar_convergence`` (registered in tracking_bench.metrics): the generic
``convergence`` family (bench_eval.metric_families) plus, per filter, the RMSE in the ground radar's own
coordinates of the raw measurements and of the filter's estimates (paper 000 Table 3), pooled over the runs
(``radar``) and per run (``radar_runs``, the same keys with a list of each run's value).

An estimate x_k and the truth at the same step are mapped through the radar's measurement function h (the
run's own sensor model, rebuilt from the bag's run config); the raw measurement z_k is the one recorded at
that step. Range errors are in metres; angle errors are wrapped to (-pi, pi] and reported in mrad
(bench_eval.metrics.radar_coordinate_rmse), and
the scenario's bounds mapped into the same coordinates (leo_radar/radar_bound.py).
"""
from __future__ import annotations

import numpy as np

from bench_eval import metrics
from bench_eval.metric_families import CONVERGENCE, Metric, Tracks
from bench_eval.scoring import BagData
from bench_studies.leo_radar.radar_bound import add_radar_bounds


def radar_samples(data: BagData, filter_name: str) -> metrics.RadarSamples | None:
    """Estimate, raw measurement and truth in the filter's (first) radar's coordinates, at every estimate step
    that has a recorded measurement (None when there is none)."""
    from tracker_filters.builders import build_filter_stack
    stack = build_filter_stack(data.scenario, filter_name)
    sensor_name = next(iter(stack.sensors))
    sensor = stack.sensors[sensor_name]
    meas = data.measurements.get(sensor_name, {})
    est = data.estimates[filter_name]
    rows = [i for i, k in enumerate(est.steps) if int(k) in meas]
    if not rows:
        return None
    t = est.t[rows]
    z_est = sensor.model.h_series(est.x[rows], t)
    z_meas = np.array([meas[int(est.steps[i])] for i in rows])
    z_true = sensor.model.h_series(np.array([data.truth[int(est.steps[i])][1] for i in rows]), t)
    return metrics.RadarSamples(z_est, z_meas, z_true, tuple(sensor.model.angle_indices))


def _score(tracks: Tracks, runs: list[BagData], options: dict) -> dict:
    radar: dict[str, metrics.RadarSamples] = {}
    per_run: dict[str, dict] = {}
    for name in tracks:
        samples = [radar_samples(d, name) for d in runs if name in d.estimates and name in d.run["filters"]]
        samples = [s for s in samples if s is not None]
        if samples:  # the runs' samples pooled: RMSE over every run and scan
            radar[name] = metrics.RadarSamples(*(np.vstack([getattr(s, k) for s in samples])
                                                 for k in ("z_est", "z_meas", "z_true")), samples[0].angle_indices)
            blocks = [metrics.radar_block(s) for s in samples]  # each run's own: the Monte Carlo spread
            per_run[name] = {src: {key: [b[src][key] for b in blocks] for key in blocks[0][src]} for src in blocks[0]}
    scored = metrics.score_convergence(tracks, radar)
    for name, block in per_run.items():
        scored[name]["radar_runs"] = metrics.json_ready(block)
    add_radar_bounds(scored, runs)
    return scored


RADAR_CONVERGENCE = Metric(options=CONVERGENCE.options, score=_score, series=CONVERGENCE.series)
