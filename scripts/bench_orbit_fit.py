#!/usr/bin/env python3
"""What grace_velocity's orbit fits cost: CPU time per satellite-day, and what they give.

Takes one run of grace_velocity's dynamic variant (``--bag``, or makes it: ``launch.py grace_velocity --variant
dynamic --seed SEED --no-score``) and runs each of its orbit-fit offline estimators (``scoring.offline`` entries of
estimator ``pair_orbit_fit``: both satellites' orbits fitted to their own GNSS fixes, orbit_sim.orbit_fit) in
this process, pinned to one CPU so the two satellites are fitted in turn and the process's CPU time is theirs.
Prints per estimator the CPU and wall time, the CPU time per satellite-day of fixes, and the RMS of the fitted
range rate against the truth's over the scoring window (the figure the study's tables report as rr_truth) and
over all the fit's steps. No
cache is read or written. Nothing is asserted: these are measurements.

Example:
  .venv/bin/python scripts/bench_orbit_fit.py                    # seed 1, both orbit fits of the scenario
  .venv/bin/python scripts/bench_orbit_fit.py --bag runs/grace/bag --estimators orbit_fit
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads: the fits' CPU time is this thread's

import numpy as np  # noqa: E402

from bench_engine import plugins  # noqa: E402
from bench_eval.scoring import load_bag, scoring_options  # noqa: E402
from bench_studies.grace_velocity.metrics import range_rate  # noqa: E402

LAUNCH = Path(__file__).resolve().parent / "launch.py"
FIT = "pair_orbit_fit"
BASELINE = ["bx", "by", "bz", "bvx", "bvy", "bvz"]
DAY_S = 86400.0


def make_bag(out: Path, seed: int) -> Path:
    cmd = [sys.executable, str(LAUNCH), "grace_velocity", "--variant", "dynamic", "--seed", str(seed)]
    done = subprocess.run([*cmd, "--no-score", "--out", str(out)], capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"error: launch.py grace_velocity failed:\n{done.stderr[-2000:]}")
    return out / "bag"


def baseline_rate(labels: list[str], x: np.ndarray) -> np.ndarray:
    cols = [labels.index(label) for label in BASELINE]
    b = x[:, cols]
    return range_rate(b[:, :3], b[:, 3:])


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--bag", type=Path, help="a grace_velocity run's bag (default: make one)")
    p.add_argument("--seed", type=int, default=1, help="the run's seed when making it (default 1)")
    p.add_argument("--estimators", help="comma-separated orbit-fit entries of scoring.offline (default: all)")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        data = load_bag(args.bag or make_bag(Path(tmp) / "run", args.seed))
    opts = scoring_options(data.scenario)
    fits = {name: job for name, job in opts.offline.items() if job.estimator == FIT}
    chosen = args.estimators.split(",") if args.estimators else list(fits)
    unknown = sorted(set(chosen) - set(fits))
    if unknown:
        sys.exit(f"error: --estimators: {unknown} are not orbit fits of this run's scenario (it has {sorted(fits)})")
    os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})  # one CPU: the two fits in turn, in this process
    steps = np.array(sorted(data.truth))
    t = np.array([data.truth[int(k)][0] for k in steps])
    truth_rate = baseline_rate(data.truth_labels, np.array([data.truth[int(k)][1] for k in steps]))
    print(f"grace_velocity dynamic, seed {data.run.get('seed')}: fixes over {(t[-1] - t[0]) / DAY_S:.3f} days")
    print(
        "| estimator | CPU [s] | wall [s] | CPU per satellite-day [s] | range-rate RMS vs truth, scoring window "
        "[µm/s] | the same over the fit's whole span [µm/s] |"
    )
    print("|---|---|---|---|---|---|")
    for name in chosen:
        job = fits[name]
        run = plugins.load("offline", job.estimator).run
        c0, w0 = time.process_time(), time.perf_counter()
        est = run(data, job.source, job.params)
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        span_days = (est.t[-1] - est.t[0]) / DAY_S
        index = np.searchsorted(t, est.t)
        inside = opts.window.inside(est.t, t[0], t[-1]) if opts.window else np.ones(len(est.t), bool)
        err = baseline_rate(est.labels, est.x) - truth_rate[index]
        print(
            f"| {name} | {cpu:.1f} | {wall:.1f} | {cpu / (2 * span_days):.1f} | "
            f"{1e6 * np.sqrt(np.mean(err[inside] ** 2)):.4f} | {1e6 * np.sqrt(np.mean(err**2)):.4f} |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
