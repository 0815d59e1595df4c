#!/usr/bin/env python3
"""Per-frame cost of the star_tracker node cores, in-process (no ROS): the star camera and each tracker.

The scenario's truth and camera run once (bench_engine.inprocess, sensors only); then every repeat drives a
fresh core of each node (star_tracker.star_camera.StarCameraStage, star_tracker.tracker_stage.
StarTrackerStage) through the same items, interleaved frame by frame as the lock-step graph delivers them,
and times each ``on_input`` call. Per node it prints the mean ms per frame over the run (the first
lost-in-space frame included), its range over the repeats and the median and p90 of the single frames.

    .venv/bin/python scripts/bench_star_tracking.py                       # the 400-frame default case
    .venv/bin/python scripts/bench_star_tracking.py --repeat 5 --variant rotation
    .venv/bin/python scripts/bench_star_tracking.py --estimators jpdaf_wahba --set star_cameras.camera.false_rate=3

Budget (issue 8): the JPDAF at most 5 ms per frame. Nothing is asserted: on a shared machine the times are
upper bounds.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bench_engine.config import load_scenario, select_variant
from bench_engine.graph import TRUTH_TOPIC, measurement_topic, resolve_estimators
from bench_engine.inprocess import run_in_process
from bench_engine.scenario import scenario_seed
from star_tracker.camera_stage import STAR_CAMERA, read_cameras
from star_tracker.tracker_stage import StarTrackerStage, read_trackers

JPDAF_BUDGET_MS = 5.0


def time_cores(cfg: dict, filters: list[str], seed: int) -> dict[str, np.ndarray]:
    """ms per frame of each node core (camera(s) and trackers) over one run of the scenario."""
    sensors = run_in_process(cfg, seed=seed, roles=("sensor",)).items
    context = {"scenario": cfg, "seed": seed}
    trackers = read_trackers(cfg)
    stages = {name: (TRUTH_TOPIC, STAR_CAMERA.stage(cfg, name, context)) for name in read_cameras(cfg)}
    stages.update(
        {name: (measurement_topic(trackers[name].camera), StarTrackerStage(cfg, name, context)) for name in filters}
    )
    ms: dict[str, list[float]] = {name: [] for name in stages}
    for k in range(len(sensors[TRUTH_TOPIC])):
        for name, (topic, stage) in stages.items():
            item = sensors[topic][k]
            t0 = time.perf_counter()
            stage.on_input(topic, item)
            ms[name].append((time.perf_counter() - t0) * 1e3)
    return {name: np.array(v) for name, v in ms.items()}


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__
    )
    ap.add_argument("--scenario", default="star_tracker")
    ap.add_argument("--variant", default=None, help="the scenario's variants, comma-separated")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override (repeatable)")
    ap.add_argument("--estimators", default=None, help="comma-separated star trackers (default: the scenario's)")
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--repeat", type=int, default=3, help="runs of the cores (default 3)")
    args = ap.parse_args()

    cfg = select_variant(load_scenario(args.scenario, args.set), args.variant)
    seed = scenario_seed(cfg) if args.seed is None else args.seed
    requested = args.estimators.split(",") if args.estimators else None
    filters = [n for n in read_trackers(cfg) if n in resolve_estimators(cfg, requested)]
    runs = [time_cores(cfg, filters, seed) for _ in range(args.repeat)]
    frames = len(next(iter(runs[0].values())))
    print(
        f"{args.scenario}{' --variant ' + args.variant if args.variant else ''}: {frames} frames, seed {seed}, "
        f"{args.repeat} repeats"
    )
    print(f"{'node':14s} {'mean ms/frame':>14s} {'range':>15s} {'median':>7s} {'p90':>7s}")
    total = np.zeros(args.repeat)
    for name in runs[0]:
        means = np.array([r[name].mean() for r in runs])
        every = np.concatenate([r[name] for r in runs])
        if name in filters:
            total += means
        print(
            f"{name:14s} {np.median(means):14.3f} {means.min():7.3f}–{means.max():<7.3f} "
            f"{np.median(every):7.3f} {np.percentile(every, 90):7.3f}"
        )
    print(
        f"{'trackers':14s} {np.median(total):14.3f} {total.min():7.3f}–{total.max():<7.3f}"
        f"   (JPDAF budget {JPDAF_BUDGET_MS} ms each)"
    )


if __name__ == "__main__":
    main()
