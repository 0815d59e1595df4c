"""Offline scoring from bags only: bag -> aligned tracks -> the scenario's metrics (bench_eval.metrics).

A bag directory written by the recorder carries the run config (``run_config.yaml``: the resolved scenario),
so the scorer rebuilds the same sensor models the run used to map estimates into radar coordinates.
Estimates are matched to truth and measurements by lock-step index (``step``), never by arrival order.
"""
from __future__ import annotations

import json
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from bench_engine.bag import BagReader
from bench_engine.config import Section
from bench_engine.graph import CLOCK_TOPIC, TRUTH_TOPIC
from bench_engine.stage import codec
from bench_eval import metrics

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
class Estimates:
    """One filter's estimates of one run, in step order."""

    steps: np.ndarray  # (K,)
    t: np.ndarray  # (K,) s
    x: np.ndarray  # (K, n)
    P: np.ndarray  # (K, n, n)
    labels: list[str]
    diagnostics: dict[str, np.ndarray]  # name -> (K,), NaN where an estimate does not carry it

    @classmethod
    def from_messages(cls, msgs: list) -> "Estimates":
        msgs = sorted(msgs, key=lambda m: m.step)
        n = len(msgs[0].labels)
        names = sorted({k for m in msgs for k in m.diagnostic_names})
        diag = {k: np.array([dict(zip(m.diagnostic_names, m.diagnostic_values)).get(k, np.nan) for m in msgs])
                for k in names}
        return cls(np.array([m.step for m in msgs]), np.array([_seconds(m.header.stamp) for m in msgs]),
                   np.array([m.state for m in msgs], dtype=float),
                   np.array([m.covariance for m in msgs], dtype=float).reshape(len(msgs), n, n),
                   list(msgs[0].labels), diag)


@dataclass
class BagData:
    """The decoded content of one run's bag (plain arrays: picklable, so bags load in parallel)."""

    run: dict
    truth: dict[int, tuple[float, np.ndarray]] = field(default_factory=dict)  # step -> (t, state)
    truth_labels: list[str] = field(default_factory=list)
    measurements: dict[str, dict[int, np.ndarray]] = field(default_factory=dict)  # sensor -> step -> z
    estimates: dict[str, Estimates] = field(default_factory=dict)

    @property
    def scenario(self) -> dict:
        return self.run["scenario"]


def _seconds(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def load_bag(bag_dir: Path | str) -> BagData:
    """Decode truth, measurements and estimates of a recorded run."""
    bag_dir = Path(bag_dir)
    config = bag_dir / "run_config.yaml"
    if not config.is_file():
        raise FileNotFoundError(f"{bag_dir} has no run_config.yaml: not a bag recorded by this bench")
    data = BagData(yaml.safe_load(config.read_text()))
    reader = BagReader(bag_dir)
    types = reader.topics()
    estimates: dict[str, list] = {}
    for topic, _t_log, msg in reader.decoded([t for t in types if t != CLOCK_TOPIC]):
        if topic == TRUTH_TOPIC:
            data.truth[msg.step] = (_seconds(msg.header.stamp), np.asarray(msg.state, dtype=float))
            data.truth_labels = list(msg.labels)
        elif topic.endswith("/measurement"):
            data.measurements.setdefault(topic.split("/")[1], {})[msg.step] = codec(types[topic]).decode(msg).z
        elif topic.endswith("/estimate"):
            estimates.setdefault(msg.filter_name, []).append(msg)
    data.estimates = {name: Estimates.from_messages(msgs) for name, msgs in estimates.items()}
    return data


def load_bags(bag_dirs: list[Path | str], jobs: int = 2) -> list[BagData]:
    """Load several bags, in ``jobs`` worker processes when there are many."""
    if len(bag_dirs) <= 2 or jobs <= 1:
        return [load_bag(b) for b in bag_dirs]
    with ProcessPoolExecutor(jobs) as pool:
        return list(pool.map(load_bag, bag_dirs, chunksize=4))


def track_of(data: BagData, filter_name: str) -> metrics.Track:
    """Estimates of one filter aligned with the truth of the same steps (truth reordered to the labels)."""
    est = data.estimates[filter_name]
    index = [data.truth_labels.index(lab) for lab in est.labels if lab in data.truth_labels]
    n = len(index)
    x_true = np.array([data.truth[int(k)][1][index] for k in est.steps])
    return metrics.Track(est.t, est.x[:, :n], est.P[:, :n, :n], x_true, est.labels[:n])


def radar_samples(data: BagData, filter_name: str) -> metrics.RadarSamples | None:
    """Estimate, raw measurement and truth in the filter's (first) sensor's coordinates, per estimate."""
    from tracker_filters.builders import build_filter_stack
    stack = build_filter_stack(data.scenario, filter_name)
    sensor_name = next(iter(stack.sensors))
    sensor = stack.sensors[sensor_name]
    meas = data.measurements.get(sensor_name, {})
    est = data.estimates[filter_name]
    rows = [i for i, k in enumerate(est.steps) if int(k) in meas]
    if not rows:
        return None
    z_est = [sensor.model.h(est.x[i], est.t[i]) for i in rows]
    z_meas = [meas[int(est.steps[i])] for i in rows]
    z_true = [sensor.model.h(data.truth[int(est.steps[i])][1], est.t[i]) for i in rows]
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
    runs = load_bags(bag_dirs)
    scenario = _scenario_name(runs)
    tracks: dict[str, list[metrics.Track]] = {}
    for data in runs:
        for name in data.run["filters"]:
            if name in data.estimates:
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
            samples = [radar_samples(d, name) for d in runs if name in d.estimates]
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


def score_run(out_dir: Path, as_json: bool = False) -> str:
    """Score the bag of one run directory (OUT/bag), save OUT/score.json, return the text to print."""
    scored = score_bags([Path(out_dir) / "bag"])
    (Path(out_dir) / "score.json").write_text(json.dumps(scored, indent=1))
    return json.dumps(scored, indent=1) if as_json else print_summary(scored)


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
