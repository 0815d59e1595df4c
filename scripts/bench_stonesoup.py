#!/usr/bin/env python3
"""Per-step time of the bench's EKF, UKF, GNN tracker and JPDAF against Stone Soup's on identical data, in
process (no ROS). tests/test_stonesoup_crosscheck.py checks that the two give the same estimates on these
problems; this script only times them (tracker_filters/crosscheck.py poses them to Stone Soup).

    .venv/bin/python scripts/bench_stonesoup.py
    .venv/bin/python scripts/bench_stonesoup.py --repeat 5 --duration 120 --targets 4 --json runs/stonesoup.json

- ekf, ukf: one step (predict 0.1 s with the two-body + J2 RK4 model, update with one radar scan) over the
  first ``--duration`` s of a leo_radar pass: the bench's ``Filter.process`` against Stone Soup's predictor +
  updater with the bench's f, F, Q, h and H (angles as floats, the variant that agrees to round-off; with
  ``--bearings`` as Stone Soup Bearings). UKF: alpha = 1, beta = 2, kappa = 0 (leo_radar's).
- gnn: one detection set (about 11 relative-position detections, one track, KF over CW dynamics) of the
  clutter_demo case of the test: the bench's ``Tracker.step`` against Stone Soup's GNNWith2DAssignment with
  hypothesiser, gater, predictor and updater.
- jpda: one frame of ``--targets`` crossing image-plane targets in Poisson clutter (25 per frame): the
  bench's ``JPDAFTracker.step`` against Stone Soup's JPDA and mixture reduction. Stone Soup enumerates the
  joint events of all tracks at once (the bench per cluster of tracks sharing detections), so its cost grows
  as the product of the tracks' hypothesis counts.

Detections are converted to Stone Soup's types before timing. Each figure is the median over the steps of a
run; with ``--repeat`` the smallest median over the repeats. Nothing is asserted; on a shared machine the times
are upper bounds.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time
from pathlib import Path

import numpy as np
from stonesoup.models.measurement.linear import LinearGaussian
from stonesoup.models.transition.linear import CombinedLinearGaussianTransitionModel
from stonesoup.models.transition.linear import ConstantVelocity as SSConstantVelocity
from stonesoup.predictor.kalman import KalmanPredictor
from stonesoup.types.array import StateVector
from stonesoup.types.detection import Detection
from stonesoup.updater.kalman import KalmanUpdater

from bench_engine.config import load_scenario
from bench_engine.inprocess import run_in_process
from star_tracker.motion import ConstantVelocity as ImageConstantVelocity
from star_tracker.tracking import JPDAFTracker
from tracker_filters.builders import build_filter_stack
from tracker_filters.crosscheck import (
    StoneSoupFilter,
    StoneSoupGNN,
    StoneSoupJPDA,
    detection,
    gaussian_track,
    timestamp,
)
from tracker_filters.tracker_stage import build_tracker

CLUTTER_DEMO = Path(__file__).resolve().parent.parent / "tests" / "data" / "clutter_demo.yaml"
LEO_FILTERS = [
    "filters.xekf.type=ekf",
    "filters.xekf.dynamics.sigma_accel=2.0",
    "filters.xukf.type=ukf",
    "filters.xukf.dynamics.sigma_accel=0.5",
    "filters.xukf.params.alpha=1.0",
    "filters.xukf.params.beta=2.0",
    "filters.xukf.params.kappa=0.0",
]
"""The recursive filters of the test: the paper's first-order EKF and leo_radar's UKF without re-solves."""


def timed(step, inputs) -> float:
    """Median wall time (µs) of step(item) over the items."""
    times = []
    for item in inputs:
        start = time.perf_counter()
        step(item)
        times.append(time.perf_counter() - start)
    return 1e6 * statistics.median(times)


def bench_leo(duration: float, seed: int, bearings: bool) -> dict[str, tuple[float, float]]:
    cfg = load_scenario("leo_radar", [f"time.duration={duration}", *LEO_FILTERS])
    run = run_in_process(cfg, ["xekf", "xukf"], seed=seed)
    scans = run.items["/radar/measurement"]
    out = {}
    for name, kind in (("xekf", "ekf"), ("xukf", "ukf")):
        first = run.items[f"/{name}/estimate"][0]
        stack = build_filter_stack(cfg, name)
        flt, model = stack.filter, stack.sensors["radar"].model
        flt.initialise(first.x, first.P, scans[0].t)
        ours = timed(lambda m, flt=flt, model=model: flt.process(m.t, m.z, m.R, model), scans[1:])
        peer = StoneSoupFilter(kind, flt.dynamics, alpha=1.0, beta=2.0, kappa=0.0)
        peer.initialise(first.x, first.P, scans[0].t)
        dets = [detection(model, m.t, m.z, m.R, peer.ndim_state, bearings) for m in scans[1:]]
        out[kind] = (ours, timed(peer.process, dets))
    return out


def bench_gnn(seed: int) -> tuple[float, float, float]:
    """(bench µs, Stone Soup µs, mean detections per set)."""
    cfg = load_scenario(
        str(CLUTTER_DEMO),
        [
            "time.duration=60",
            "cluttered_sensors.cam.clutter_rate=10.0",
            "cluttered_sensors.cam.clutter_halfwidth=[3.0,3.0,3.0]",
        ],
    )
    sets = run_in_process(cfg, ["kf"], seed=seed, roles=("sensor",)).items["/cam/detections"]
    tracker = build_tracker(cfg, "gnn")
    tracker.step(sets[0].t, sets[0].Z, sets[0].R)
    flt = tracker.tracks[0].filter
    peer, track = StoneSoupGNN(flt.dynamics, tracker.gate_probability), gaussian_track(flt.x, flt.P, flt.t)
    ours = timed(lambda d: tracker.step(d.t, d.Z, d.R), sets[1:])
    inputs = [
        (
            d.t,
            [
                Detection(StateVector(z), timestamp=timestamp(d.t), measurement_model=LinearGaussian(6, (0, 1, 2), r))
                for z, r in zip(d.Z, d.R)
            ],
        )
        for d in sets[1:]
    ]
    return (
        ours,
        timed(lambda item: peer.step([track], item[1], item[0]), inputs),
        float(np.mean([len(d.Z) for d in sets[1:]])),
    )


def bench_jpda(targets: int, frames: int, seed: int) -> tuple[float, float]:
    rng = np.random.default_rng(seed)
    dt, sigma, p_detect, q, box, clutter_rate = 0.1, 0.5, 0.9, 4.0, 40.0, 25.0
    density = clutter_rate / box**2
    angle = np.linspace(0.0, math.pi, targets, endpoint=False)  # lines crossing near the box centre
    truth = np.column_stack(
        [20.0 - 8.0 * np.cos(angle), 10.0 * np.cos(angle), 20.0 - 8.0 * np.sin(angle), 10.0 * np.sin(angle)]
    )
    F = np.kron(np.eye(2), [[1.0, dt], [0.0, 1.0]])
    start, sets = truth.copy(), []
    for _ in range(frames):
        truth = truth @ F.T
        seen = (truth[:, [0, 2]] + rng.normal(0, sigma, (targets, 2)))[rng.random(targets) < p_detect]
        Z = np.vstack([seen, rng.uniform(0, box, (rng.poisson(clutter_rate), 2))])
        sets.append(Z[rng.permutation(len(Z))])
    ours = JPDAFTracker(
        ImageConstantVelocity(math.sqrt(q), kind="continuous"), sigma, p_detect, density, max_misses=10**6
    )
    ours.start(np.arange(targets), start[:, [0, 2]], start[:, [1, 3]], velocity_sigma=1.0)
    measurement = LinearGaussian(4, (0, 2), np.diag([sigma**2, sigma**2]))
    predictor = KalmanPredictor(CombinedLinearGaussianTransitionModel([SSConstantVelocity(q), SSConstantVelocity(q)]))
    peer = StoneSoupJPDA(predictor, KalmanUpdater(measurement), p_detect, density, ours.gate_probability)
    tracks = [gaussian_track(x, P, 0.0) for x, P in zip(ours.x, ours.P)]
    inputs = [
        (
            (k + 1) * dt,
            [Detection(StateVector(z), timestamp=timestamp((k + 1) * dt), measurement_model=measurement) for z in Z],
        )
        for k, Z in enumerate(sets)
    ]
    return timed(lambda Z: ours.step(Z, dt), sets), timed(lambda item: peer.step(tracks, item[1], item[0]), inputs)


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__
    )
    ap.add_argument("--repeat", type=int, default=3, help="runs of each case; the smallest median is kept")
    ap.add_argument("--duration", type=float, default=60.0, help="seconds of the leo_radar pass (default 60)")
    ap.add_argument("--bearings", action="store_true", help="radar angles as Stone Soup Bearings, not floats")
    ap.add_argument("--targets", type=int, default=3, help="JPDA targets (default 3)")
    ap.add_argument("--frames", type=int, default=40, help="JPDA frames (default 40)")
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--json", default=None, help="also write the figures to this file")
    args = ap.parse_args()

    rows: dict[str, list[tuple[float, float]]] = {}
    extra = {}
    for _ in range(args.repeat):
        for kind, pair in bench_leo(args.duration, args.seed, args.bearings).items():
            rows.setdefault(kind, []).append(pair)
        ours, peer, extra["gnn_detections_per_set"] = bench_gnn(args.seed)
        rows.setdefault("gnn", []).append((ours, peer))
        rows.setdefault("jpda", []).append(bench_jpda(args.targets, args.frames, args.seed))
    labels = {
        "ekf": "EKF step (leo_radar: predict 0.1 s + radar update)",
        "ukf": "UKF step (alpha 1, beta 2, kappa 0)",
        "gnn": f"GNN tracker, one set ({extra['gnn_detections_per_set']:.1f} detections, one track)",
        "jpda": f"JPDA, one frame ({args.targets} targets, ~25 clutter)",
    }
    print(f"{'per step, median':60s} {'bench µs':>10s} {'Stone Soup µs':>14s} {'ratio':>7s}")
    report = {"repeat": args.repeat, "bearings": args.bearings, **extra}
    for kind, pairs in rows.items():
        ours, peer = min(p[0] for p in pairs), min(p[1] for p in pairs)
        report[kind] = {"bench_us": ours, "stonesoup_us": peer, "ratio": peer / ours}
        print(f"{labels[kind]:60s} {ours:10.1f} {peer:14.1f} {peer / ours:6.1f}×")
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
