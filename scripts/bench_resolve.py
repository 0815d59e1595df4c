#!/usr/bin/env python3
"""Cost of the Gauss-Newton batch re-solves of the leo_radar filters (tracker_filters/relinearisation.py).

Builds the leo_radar scenario as the graph does (truth, radar with P_D = 0.95, first-scan prior of the
default "ekf" filter), keeps the first N scans of the pass in a PassBatch and times, for each N:
one ``linearise`` at the true state at t0 (ms, and us per scan) and one full ``solve`` started from it
(ms, with its number of linearisations). Best of ``--repeats``.

    .venv/bin/python scripts/bench_resolve.py                       # N = 500 1000 2000 4000
    .venv/bin/python scripts/bench_resolve.py --scans 4000 --generic # the per-scan loop, for comparison
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads, as in the graph (bench_engine.launcher)

from bench_engine.config import load_scenario  # noqa: E402
from bench_engine.inprocess import run_in_process  # noqa: E402
from radar_sensor.sensor import build_sensor  # noqa: E402
from tracker_filters.builders import build_filter_stack  # noqa: E402
from tracker_filters.relinearisation import PassBatch  # noqa: E402


def pass_scans(seed: int):
    """(dynamics, prior (x0, P0, t0), true state at t0, scans [(t, z)], R, model) of one leo_radar pass; the
    radar's scans are drawn by the graph's own cores in process (truth and sensor only)."""
    cfg = load_scenario("leo_radar")
    run = run_in_process(cfg, seed=seed, roles=("sensor",))
    sensor = build_sensor(cfg, "radar")
    stack = build_filter_stack(cfg, "ekf")
    first, *rest = run.items["/radar/measurement"]
    x_t0 = next(s.state for s in run.items["/truth/state"] if s.step == first.step)
    prior = (*stack.initialise(first.z, first.R, sensor, first.t), first.t)
    return stack.filter.dynamics, prior, x_t0, [(m.t, m.z) for m in rest], sensor.R, sensor.model


def best_time(fn, repeats: int) -> tuple[float, object]:
    """Smallest wall-clock seconds of ``repeats`` calls of fn, and its last result."""
    best, out = float("inf"), None
    for _ in range(repeats):
        start = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - start)
    return best, out


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=__doc__.split("\n\n", 1)[1],
    )
    parser.add_argument(
        "--scans",
        type=int,
        nargs="+",
        default=[500, 1000, 2000, 4000],
        help="numbers of stored scans (default 500 1000 2000 4000; capped at the pass's)",
    )
    parser.add_argument("--repeats", type=int, default=3, help="repeats; the best is shown (default 3)")
    parser.add_argument("--generic", action="store_true", help="force the per-scan loop (PassBatch(vectorised=False))")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    dynamics, (m0, P0, t0), x_t0, scans, R, model = pass_scans(args.seed)
    options = {"vectorised": False} if args.generic else {}
    print(
        f"leo_radar: {len(scans)} scans after the first; {'generic loop' if args.generic else 'default path'}"
        f", best of {args.repeats}"
    )
    print(f"{'scans':>6}{'linearise ms':>14}{'us/scan':>9}{'solve ms':>10}{'passes':>8}")
    for n in args.scans:
        n = min(n, len(scans))
        batch = PassBatch(dynamics, m0, P0, t0, **options)
        for t, z in scans[:n]:
            batch.add(t, z, R, model)
        lin, _ = best_time(lambda b=batch: b.linearise(x_t0), args.repeats)
        sol, (_, _, passes) = best_time(lambda b=batch: b.solve(x_t0), args.repeats)
        print(f"{n:>6}{lin * 1e3:>14.1f}{lin / n * 1e6:>9.1f}{sol * 1e3:>10.1f}{passes:>8}")


if __name__ == "__main__":
    main()
