"""The leo_radar metric family ``radar_convergence`` (registered in tracking_bench.metrics): the generic
``convergence`` family (bench_eval.metric_families) plus, per filter, the RMSE in the ground radar's own
coordinates of the raw measurements and of the filter's estimates (paper 000 Table 3), pooled over the runs
(``radar``) and per run (``radar_runs``, the same keys with a list of each run's value).

An estimate x_k and the truth at the same step are mapped through the radar's measurement function h (the
run's own sensor model, rebuilt from the bag's run config); the raw measurement z_k is the one recorded at
that step. Range errors are in metres; angle errors are wrapped to (-pi, pi] and reported in mrad
(:func:`radar_coordinate_rmse`), and the scenario's bounds mapped into the same coordinates
(leo_radar/radar_bound.py).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bench_engine.settings import NoKeys
from bench_eval import metrics
from bench_eval.metric_families import CONVERGENCE, Metric, Tracks
from bench_eval.scoring import BagData
from bench_studies.leo_radar.radar_bound import RADAR_UNITS, add_radar_bounds
from orbit_sim.angles import wrapped_residual
from tracker_filters.builders import build_filter_stack


def _rows(z: np.ndarray | Sequence[np.ndarray]) -> np.ndarray:
    """Stack per-run arrays (K_i, d) (or one (..., d) array) into (M, d) rows."""
    if isinstance(z, np.ndarray):
        return z.reshape(-1, z.shape[-1]).astype(float)
    return np.concatenate([np.asarray(a, dtype=float) for a in z], axis=0)


def radar_coordinate_rmse(
    z_est: np.ndarray | Sequence[np.ndarray],
    z_meas: np.ndarray | Sequence[np.ndarray],
    z_true: np.ndarray | Sequence[np.ndarray],
    angle_indices: Sequence[int] = (1, 2),
) -> dict[str, np.ndarray]:
    """RMSE per measurement component of the filter and of the raw measurements (paper 000 Table 3).

    ``z_est`` is the filter estimate mapped into measurement space (h(x_est)), ``z_meas`` the raw
    measurements and ``z_true`` h(x_true), all aligned row by row: arrays (..., d) or per-run lists of
    (K_i, d). Angle differences are wrapped to (-pi, pi]. Rows with NaN (e.g. a missed detection in
    ``z_meas``) are left out of that source's RMSE. Returns {"filter": (d,), "measurement": (d,)}.
    """
    truth = _rows(z_true)
    out = {}
    for name, z in (("filter", z_est), ("measurement", z_meas)):
        e = wrapped_residual(_rows(z), truth, angle_indices)
        out[name] = np.sqrt(np.nanmean(e**2, axis=0))
    return out


@dataclass
class RadarSamples:
    """Radar-coordinate arrays for :func:`radar_coordinate_rmse`: (range, azimuth, elevation) rows."""

    z_est: np.ndarray | Sequence[np.ndarray]
    z_meas: np.ndarray | Sequence[np.ndarray]
    z_true: np.ndarray | Sequence[np.ndarray]
    angle_indices: Sequence[int] = (1, 2)


def radar_block(samples: RadarSamples) -> dict:
    """Table 3 block: {"filter": {range_m, azimuth_mrad, elevation_mrad}, "measurement": {...}}."""
    r = radar_coordinate_rmse(samples.z_est, samples.z_meas, samples.z_true, samples.angle_indices)
    return {src: {key: float(v * scale) for (key, scale), v in zip(RADAR_UNITS, r[src])} for src in r}


def radar_samples(data: BagData, filter_name: str) -> RadarSamples | None:
    """Estimate, raw measurement and truth in the filter's (first) radar's coordinates, at every estimate step
    that has a recorded measurement (None when there is none)."""
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
    return RadarSamples(z_est, z_meas, z_true, tuple(sensor.model.angle_indices))


def score_radar_convergence(tracks: Tracks, radar: dict[str, RadarSamples]) -> dict:
    """The ``convergence`` family's scores, with each filter of ``radar`` given its ``radar`` block (pooled
    samples)."""
    scored = metrics.score_convergence(tracks)
    for name, samples in radar.items():
        scored[name]["radar"] = metrics.json_ready(radar_block(samples))
    return scored


def _score(tracks: Tracks, runs: list[BagData], options: NoKeys) -> dict:
    radar: dict[str, RadarSamples] = {}
    per_run: dict[str, dict] = {}
    for name in tracks:
        samples = [radar_samples(d, name) for d in runs if name in d.estimates and name in d.run["estimators"]]
        samples = [s for s in samples if s is not None]
        if samples:  # the runs' samples pooled: RMSE over every run and scan
            radar[name] = RadarSamples(
                *(np.vstack([getattr(s, k) for s in samples]) for k in ("z_est", "z_meas", "z_true")),
                samples[0].angle_indices,
            )
            blocks = [radar_block(s) for s in samples]  # each run's own: the Monte Carlo spread
            per_run[name] = {src: {key: [b[src][key] for b in blocks] for key in blocks[0][src]} for src in blocks[0]}
    scored = score_radar_convergence(tracks, radar)
    for name, block in per_run.items():
        scored[name]["radar_runs"] = metrics.json_ready(block)
    add_radar_bounds(scored, runs)
    return scored


def _summary(block: dict) -> list[str]:
    """The radar block in the scorer's one-line summary (bench_eval.summary.print_summary)."""
    if "radar" not in block:
        return []
    f, m = block["radar"]["filter"], block["radar"]["measurement"]
    return ["radar filter/raw: " + ", ".join(f"{k} {f[k]:.4g}/{m[k]:.4g}" for k in f)]


RADAR_CONVERGENCE = Metric(options=CONVERGENCE.options, score=_score, series=CONVERGENCE.series, summary=_summary)
