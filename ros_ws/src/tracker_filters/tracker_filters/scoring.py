"""Offline scoring from bags only: bag -> aligned tracks -> the scenario's metrics (tracker_filters.metrics).

A bag directory written by the recorder carries the run config (``run_config.yaml``: the resolved scenario),
so the scorer rebuilds the same sensor models the run used to map estimates into radar coordinates.
Estimates are matched to truth and measurements by lock-step index (``step``), never by arrival order.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from orbit_sim.bag import BagReader
from orbit_sim.config import Section
from orbit_sim.graph import TRUTH_TOPIC
from tracker_filters import metrics

METRICS = ("leo", "formation")


def scoring_options(cfg: dict) -> dict:
    """The scenario's ``scoring`` section, checked: metric family and its options."""
    sec = Section(cfg.get("scoring"), "scoring")
    opts = {"metric": sec.choice("metric", METRICS, "leo"),
            "skip_s": sec.non_negative("skip_s", 0.0),
            "position_threshold": sec.positive("position_threshold", 0.5),
            "velocity_threshold": sec.positive("velocity_threshold", 0.02)}
    sec.finish()
    return opts


@dataclass
class BagData:
    """The decoded content of one run's bag."""

    run: dict
    truth: dict[int, tuple[float, np.ndarray]] = field(default_factory=dict)  # step -> (t, state)
    truth_labels: list[str] = field(default_factory=list)
    measurements: dict[str, dict[int, np.ndarray]] = field(default_factory=dict)  # sensor -> step -> z
    estimates: dict[str, list] = field(default_factory=dict)  # filter -> [StateEstimate msgs]

    @property
    def scenario(self) -> dict:
        return self.run["scenario"]


def load_bag(bag_dir: Path | str) -> BagData:
    """Decode truth, measurements and estimates of a recorded run."""
    bag_dir = Path(bag_dir)
    config = bag_dir / "run_config.yaml"
    if not config.is_file():
        raise FileNotFoundError(f"{bag_dir} has no run_config.yaml: not a bag recorded by this bench")
    data = BagData(yaml.safe_load(config.read_text()))
    from radar_sensor.messages import from_message
    for topic, _t_log, msg in BagReader(bag_dir).decoded():
        if topic == TRUTH_TOPIC:
            data.truth[msg.step] = (msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9,
                                    np.asarray(msg.state, dtype=float))
            data.truth_labels = list(msg.labels)
        elif topic.endswith("/measurement"):
            data.measurements.setdefault(topic.split("/")[1], {})[msg.step] = from_message(msg)[1]
        elif topic.endswith("/estimate"):
            data.estimates.setdefault(msg.filter_name, []).append(msg)
    return data


def track_of(data: BagData, filter_name: str) -> metrics.Track:
    """Estimates of one filter aligned with the truth of the same steps (truth reordered to the labels)."""
    msgs = sorted(data.estimates[filter_name], key=lambda m: m.step)
    labels = list(msgs[0].labels)
    index = [data.truth_labels.index(lab) for lab in labels if lab in data.truth_labels]
    n = len(index)
    t = np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in msgs])
    x = np.array([np.asarray(m.state)[:n] for m in msgs])
    P = np.array([np.asarray(m.covariance).reshape(len(labels), len(labels))[:n, :n] for m in msgs])
    x_true = np.array([data.truth[m.step][1][index] for m in msgs])
    return metrics.Track(t, x, P, x_true, labels[:n])


def radar_samples(data: BagData, filter_name: str) -> metrics.RadarSamples | None:
    """Estimate, raw measurement and truth in the filter's (first) sensor's coordinates, per estimate."""
    from tracker_filters.builders import build_filter_stack
    stack = build_filter_stack(data.scenario, filter_name)
    sensor_name = next(iter(stack.sensors))
    sensor = stack.sensors[sensor_name]
    meas = data.measurements.get(sensor_name, {})
    z_est, z_meas, z_true = [], [], []
    for m in sorted(data.estimates[filter_name], key=lambda m: m.step):
        if m.step not in meas:
            continue
        t = m.header.stamp.sec + m.header.stamp.nanosec * 1e-9
        z_est.append(sensor.model.h(np.asarray(m.state), t))
        z_meas.append(meas[m.step])
        z_true.append(sensor.model.h(data.truth[m.step][1], t))
    if not z_est:
        return None
    return metrics.RadarSamples(np.array(z_est), np.array(z_meas), np.array(z_true),
                                tuple(sensor.model.angle_indices))


def formation_series(tracks_by_filter: dict[str, list[metrics.Track]]) -> dict:
    """Per filter: t (s from the first stamp), RMS error over runs and mean 1-sigma per state component."""
    t0 = min(float(tr.t[0]) for tracks in tracks_by_filter.values() for tr in tracks)
    series = {}
    for name, tracks in tracks_by_filter.items():
        comps = [c for c in tracks[0].labels if c in metrics.POSITION + metrics.VELOCITY]
        t, _ = metrics.rmse_over_runs(tracks, comps[:1])
        rmse, sigma = {}, {}
        for c in comps:
            i = tracks[0].labels.index(c)
            rmse[c] = metrics.rmse_over_runs(tracks, [c])[1]
            sigma[c] = np.nanmean(metrics.on_grid(tracks, [np.sqrt(tr.P[:, i, i]) for tr in tracks])[1], axis=0)
        series[name] = {"t": t - t0, "rmse": rmse, "sigma": sigma}
    return series


def _scenario_name(runs: list[BagData]) -> str:
    names = {d.scenario.get("scenario") for d in runs}
    if len(names) != 1:
        raise ValueError(f"bags of different scenarios cannot be scored together: {sorted(map(str, names))}")
    return names.pop()


def collect(bag_dirs: list[Path | str]) -> tuple[str, dict[str, list[metrics.Track]], list[BagData]]:
    runs = [load_bag(b) for b in bag_dirs]
    scenario = _scenario_name(runs)
    tracks: dict[str, list[metrics.Track]] = {}
    for data in runs:
        for name in data.run["filters"]:
            if data.estimates.get(name):
                tracks.setdefault(name, []).append(track_of(data, name))
    return scenario, tracks, runs


def score_bags(bag_dirs: list[Path | str], with_series: bool = False):
    """Score one or more bags of the same scenario (several bags = Monte Carlo runs, paper eq. 35).

    Returns {"scenario", "runs", "filters": {name: metrics}} (and the plot series when ``with_series``).
    """
    scenario, tracks, runs = collect(bag_dirs)
    opts = scoring_options(runs[0].scenario)
    if opts["metric"] == "leo":
        radar: dict[str, metrics.RadarSamples] = {}
        for name in tracks:
            samples = [radar_samples(d, name) for d in runs if d.estimates.get(name)]
            samples = [s for s in samples if s is not None]
            if samples:
                radar[name] = metrics.RadarSamples(np.vstack([s.z_est for s in samples]),
                                                   np.vstack([s.z_meas for s in samples]),
                                                   np.vstack([s.z_true for s in samples]),
                                                   samples[0].angle_indices)
        scored = metrics.score_leo(tracks, radar)
        series = metrics.leo_series(tracks) if with_series else None
    else:
        scored = metrics.score_formation(tracks, skip_s=opts["skip_s"],
                                         position_threshold=opts["position_threshold"],
                                         velocity_threshold=opts["velocity_threshold"])
        series = formation_series(tracks) if with_series else None
    result = {"scenario": scenario, "runs": len(runs), "filters": scored}
    return (result, series) if with_series else result


def print_summary(scored: dict) -> str:
    """A short human-readable table of the main numbers."""
    lines = [f"{scored['scenario']} — {scored['runs']} run(s)"]
    for name, block in scored["filters"].items():
        parts = []
        for key, unit in (("rmse_converged_m", "m"), ("rmse_peak_m", "m"), ("convergence_time_s", "s"),
                          ("nees_mean", "")):
            if key in block:
                v = block[key]
                parts.append(f"{key}={'n/a' if v is None else f'{v:.4g}'}{unit}")
        if "band_m" in block and block["band_m"]:
            lo, hi = block["band_m"]
            parts.append(f"band=[{lo:.4g}, {hi:.4g}] m" if lo is not None else "band=n/a")
        if "radar" in block:
            f, m = block["radar"]["filter"], block["radar"]["measurement"]
            parts.append("radar filter/raw: " + ", ".join(f"{k} {f[k]:.4g}/{m[k]:.4g}" for k in f))
        if "mae" in block:
            settle = block.get("settling_time_s")
            parts.append(f"settled after {'never' if settle is None else f'{settle:.0f} s'}")
            parts.append("MAE " + ", ".join(f"{k} {v:.3g}" for k, v in block["mae"].items()))
            inside = block.get("within_3sigma") or {}
            if inside:
                parts.append(f"within 3 sigma {min(inside.values()):.0%}..{max(inside.values()):.0%}")
        lines.append(f"  {name}: " + "; ".join(parts))
    return "\n".join(lines)
