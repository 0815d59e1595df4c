"""The star_tracker metric family ``star_attitude`` (registered in tracking_bench.metrics), from the bag alone.

Per estimator (attitude quaternions, labels qw qx qy qz; the scorer's error is the rotation vector of
q_est conj(q_true), in the camera frame: bench_models.states):
- ``rms_arcsec``: the paper's figure (eq. 20: the angle between the estimated and the true attitude), RMS over
  the scored frames of every run (after ``skip_s``), with ``rms_arcsec_runs`` per run; ``cross_arcsec`` and
  ``roll_arcsec``: RMS of the cross-boresight part |(rx, ry)| and of the roll |rz|; ``max_arcsec``;
- ``nees``: mean of e' P^-1 e over the scored frames (3 dof: 3 when the covariance tells the truth);
- ``solved``: the fraction of frames with an attitude; ``first_fix_s``: time of the first attitude;
- ``lost_in_space``, ``reacquisitions``, ``filter_resets``: the tracker's own diagnostics (counts at the end
  of a run, mean over runs);
- from the estimator's ``/NAME/stars`` against the camera's ``/CAMERA/star_truth`` (same step, same centroid
  order): ``identification_rate`` (true star centroids given their own id), ``false_ids`` (centroids given a
  wrong id, false stars included, per frame), ``centroid_arcsec`` (RMS of the position each used star had in
  the fit minus its noise-free position: measured for SNA, filtered for the JPDAF; tangent units ~ rad);
- ``case``: the run's motion (boresight), jitter and centroid σ, so that the report finds the paper's table;
- ``gain_pct`` (JPDAF estimators): 100 (SNA - JPDAF) / SNA of rms_arcsec for the SNA estimator of the same
  solver (the paper's "improvement"), with ``gain_pct_runs``.

Options (``scoring`` section): ``camera`` (the star camera whose truth topic is read, default "camera"),
``skip_s`` (frames before it are not scored, default 0).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench_engine.bag_reader import BagReader
from bench_engine.settings import NON_NEGATIVE, Settings, setting
from bench_engine.timegrid import build_time
from bench_eval.metric_families import Metric, Tracks
from bench_eval.scoring import BagData
from orbit_sim.truth import read_truth
from star_tracker.camera_stage import read_cameras

ARCSEC = np.pi / (180.0 * 3600.0)


@dataclass(frozen=True, kw_only=True)
class StarAttitudeOptions(Settings):
    """The ``star_attitude`` family's keys of the ``scoring`` section."""

    camera: str = setting("camera", doc="the star camera whose star_truth scores the identification")
    skip_s: float = setting(0.0, unit="s", check=NON_NEGATIVE, doc="the start of each run not scored")


def _errors(track, t_from: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, error vectors (K, 3) rad, covariances (K, 3, 3)) of one run's estimates from t_from on."""
    keep = track.t >= t_from
    return track.t[keep], track.error()[keep], track.P[keep]


def _start(data: BagData) -> float:
    """Sim time of the run's first truth sample."""
    return min(v[0] for v in data.truth.values()) if data.truth else 0.0


def _dt(data: BagData) -> float:
    return build_time(data.scenario).dt


def _rms(values) -> float:
    values = np.asarray(values, dtype=float)
    return float(np.sqrt(np.mean(values**2))) if values.size else float("nan")


def _stars(data: BagData, camera: str, names: list[str]) -> dict[str, dict[int, object]]:
    """step -> decoded StarCentroids message of the camera's truth ("truth") and each estimator's stars."""
    bag = Path(data.run["bag_dir"])
    reader = BagReader(bag)
    topics = {f"/{camera}/star_truth": "truth", **{f"/{n}/stars": n for n in names}}
    present = [t for t in reader.topics() if t in topics]
    return {
        topics[topic]: {step: tab.row(i) for i, step in enumerate(tab["step"].tolist())}
        for topic, tab in reader.tables(present).items()
    }


def _identification(stars: dict, name: str, skip_steps: int) -> tuple[float, float, float]:
    """(identification rate, false ids per frame, centroid RMS arcsec) of one estimator in one run."""
    truth, own = stars.get("truth", {}), stars.get(name, {})
    true_stars = right = wrong = frames = 0
    dpos = []
    for step, msg in own.items():
        ref = truth.get(step)
        if ref is None or step < skip_steps or len(ref.star_id) != len(msg.star_id):
            continue
        frames += 1
        tid, sid = np.asarray(ref.star_id), np.asarray(msg.star_id)
        true_stars += int(np.sum(tid >= 0))
        right += int(np.sum((sid >= 0) & (sid == tid)))
        wrong += int(np.sum((sid >= 0) & (sid != tid)))
        used = np.isfinite(np.asarray(msg.x)) & (sid >= 0) & (sid == tid)
        if used.any():
            d = np.hypot(
                np.asarray(msg.x)[used] - np.asarray(ref.x)[used], np.asarray(msg.y)[used] - np.asarray(ref.y)[used]
            )
            dpos.append(d)
    rate = right / true_stars if true_stars else float("nan")
    centroid = _rms(np.concatenate(dpos)) / ARCSEC if dpos else float("nan")
    return rate, (wrong / frames if frames else float("nan")), centroid


def _run_block(track, data: BagData, name: str, stars: dict, options: StarAttitudeOptions) -> dict:
    t0, dt, frames = _start(data), _dt(data), len(data.truth)
    t, e, P = _errors(track, t0 + options.skip_s)
    est = data.estimates[name]
    angle = np.linalg.norm(e, axis=1)
    nees = [float(ei @ np.linalg.solve(Pi, ei)) for ei, Pi in zip(e, P) if np.all(np.isfinite(Pi))]
    rate, false_ids, centroid = _identification(stars, name, int(round(options.skip_s / dt)))
    last = {
        k: float(v[np.isfinite(v)][-1]) if np.isfinite(v).any() else float("nan") for k, v in est.diagnostics.items()
    }
    return {
        "rms_arcsec": _rms(angle) / ARCSEC,
        "cross_arcsec": _rms(np.hypot(e[:, 0], e[:, 1])) / ARCSEC,
        "roll_arcsec": _rms(e[:, 2]) / ARCSEC,
        "max_arcsec": float(angle.max() / ARCSEC) if len(angle) else float("nan"),
        "nees": float(np.mean(nees)) if nees else float("nan"),
        "solved": len(est.steps) / frames if frames else float("nan"),
        "first_fix_s": float(est.t[0] - t0) if len(est.t) else float("nan"),
        "lost_in_space": last.get("lost_in_space", float("nan")),
        "reacquisitions": last.get("reacquisitions", float("nan")),
        "filter_resets": last.get("filter_resets", float("nan")),
        "identification_rate": rate,
        "false_ids": false_ids,
        "centroid_arcsec": centroid,
        "series": (np.round((t - t0) / dt).astype(int), angle / ARCSEC),
    }


KEYS = (
    "rms_arcsec",
    "cross_arcsec",
    "roll_arcsec",
    "max_arcsec",
    "nees",
    "solved",
    "first_fix_s",
    "lost_in_space",
    "reacquisitions",
    "filter_resets",
    "identification_rate",
    "false_ids",
    "centroid_arcsec",
)


def _per_run(tracks: Tracks, runs: list[BagData], options: StarAttitudeOptions) -> dict[str, list[dict]]:
    names = list(tracks)
    out: dict[str, list[dict]] = {n: [] for n in names}
    index = {n: 0 for n in names}
    for data in runs:
        present = [n for n in names if n in data.estimates]
        stars = _stars(data, options.camera, present)
        for n in present:
            out[n].append(_run_block(tracks[n][index[n]], data, n, stars, options))
            index[n] += 1
    return out


def scenario_case(cfg: dict) -> dict:
    """The scenario's case as the paper's tables name it: the truth's boresight and jitter, the camera's
    sigma_px (None without a camera named ``camera``)."""
    truth, cameras = read_truth(cfg).options, read_cameras(cfg)
    return {
        "boresight": truth.boresight,
        "jitter_deg_s": truth.jitter_deg_s,
        "sigma_px": cameras["camera"].sigma_px if "camera" in cameras else None,
    }


def score(tracks: Tracks, runs: list[BagData], options: StarAttitudeOptions) -> dict:
    per_run = _per_run(tracks, runs, options)
    scored = {}
    for name, blocks in per_run.items():
        block = {}
        for key in KEYS:
            values = [b[key] for b in blocks]
            block[key] = float(np.nanmean(values)) if np.isfinite(values).any() else None
            block[f"{key}_runs"] = [None if not np.isfinite(v) else float(v) for v in values]
        # the RMS over every scored frame of every run (not the mean of the runs' RMS)
        angles = np.concatenate([b["series"][1] for b in blocks]) if blocks else np.zeros(0)
        block["rms_arcsec"] = _rms(angles) if angles.size else None
        block["runs"] = len(blocks)
        block["case"] = scenario_case(runs[0].scenario) if runs else {}
        scored[name] = block
    for name, block in scored.items():
        sna = scored.get(name.replace("jpdaf", "sna")) if "jpdaf" in name else None
        if sna is None or not block.get("rms_arcsec") or not sna.get("rms_arcsec"):
            continue
        block["gain_pct"] = 100.0 * (sna["rms_arcsec"] - block["rms_arcsec"]) / sna["rms_arcsec"]
        block["gain_pct_runs"] = [
            None if a is None or b is None else 100.0 * (b - a) / b
            for a, b in zip(block["rms_arcsec_runs"], sna["rms_arcsec_runs"])
        ]
    return scored


def series(tracks: Tracks, runs: list[BagData], options: StarAttitudeOptions) -> dict:
    """Per estimator: frame index, its time ``t`` and the attitude error (arcsec) per frame, RMS over the runs.
    ``t`` has the origin of the bound series (bench_eval.bounds.score_bounds: the first estimate of any
    estimator), so that √bound can be drawn on the same axis."""
    out = {}
    first = min((float(tr.t[0]) for group in tracks.values() for tr in group if len(tr.t)), default=None)
    offset = _start(runs[0]) - first if runs and first is not None else 0.0
    dt = _dt(runs[0]) if runs else 0.1
    for name, blocks in _per_run(tracks, runs, options).items():
        per_frame: dict[int, list[float]] = {}
        for b in blocks:
            for k, a in zip(*b["series"]):
                per_frame.setdefault(int(k), []).append(float(a))
        frames = sorted(per_frame)
        out[name] = {
            "frame": frames,
            "t": [k * dt + offset for k in frames],
            "error_arcsec": [_rms(per_frame[k]) for k in frames],
        }
    return out


STAR_ATTITUDE = Metric(StarAttitudeOptions, score, series)
