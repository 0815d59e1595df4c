#!/usr/bin/env python3
"""Time per step of the formation filters, in-process (no ROS): particle filters and the CQKF.

Models: ``bench_models.relative_dynamics`` (CW 6-state, CW + bias 9-state) and ``bench_models.isl``
(range/azimuth/elevation on the relative state), 1 s steps along a noise-free CW truth at 1 km, paper 001's
measurement accuracy (2 cm, 0.01°). One step = ``Filter.process`` (predict + update + the base-class guards).
Targets: PF with N = 10 000 ≤ 5 ms, CQKF n' = 2 on the 9-state model ≤ 300 µs (medians after a warm-up;
the machine's other load inflates them, so the CPU time of this process is printed too). OpenBLAS runs
single-threaded, as in the graph (bench_engine.launcher).
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads, as the graph runs

import numpy as np  # noqa: E402

from bench_models.isl import RangeAzElModel  # noqa: E402
from bench_models.relative_dynamics import CWBiasDynamics, CWDynamics  # noqa: E402
from tracker_filters.cqkf import CubatureQuadratureKF  # noqa: E402
from tracker_filters.filter_base import Filter  # noqa: E402
from tracker_filters.pf import RegularisedParticleFilter, SIRParticleFilter  # noqa: E402

N_MEAN_MOTION = 2.0 * np.pi / 7200.0
R = np.diag([0.02**2, np.radians(0.01) ** 2, np.radians(0.01) ** 2])


def time_steps(f: Filter, dim: int, steps: int, warmup: int, seed: int) -> tuple[float, float, float]:
    """Median wall and CPU seconds per ``process`` call, and the 90th-percentile wall time."""
    model = RangeAzElModel()
    rng = np.random.default_rng(seed)
    truth = np.zeros(dim)
    truth[0:3] = [600.0, 700.0, 300.0]
    P0 = np.diag([25.0] * 3 + [0.01] * 3 + [1e-8] * (dim - 6))
    f.initialise(truth + rng.normal(size=dim) * np.sqrt(np.diag(P0)), P0, 0.0)
    wall, cpu = [], []
    for k in range(1, warmup + steps + 1):
        truth = f.dynamics.propagate(truth, 1.0)
        z = model.h(truth) + rng.normal(size=3) * np.sqrt(np.diag(R))
        w0, c0 = time.perf_counter(), time.process_time()
        step = f.process(float(k), z, R, model)
        if k > warmup:
            wall.append(time.perf_counter() - w0)
            cpu.append(time.process_time() - c0)
        if not step.accepted:
            raise RuntimeError(f"{f.name}: step {k} rejected: {step.reason}")
    return float(np.median(wall)), float(np.median(cpu)), float(np.percentile(wall, 90))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--particles", type=int, default=10_000, help="N for the particle filters")
    parser.add_argument("--order", type=int, default=2, help="CQKF radial order n'")
    parser.add_argument("--steps", type=int, default=200, help="timed steps per filter")
    parser.add_argument("--warmup", type=int, default=20, help="untimed steps first (PF convergence)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    cw = CWDynamics(N_MEAN_MOTION, sigma_accel=1e-3)
    cw_bias = CWBiasDynamics(N_MEAN_MOTION, sigma_accel=1e-3, sigma_bias=1e-6)
    cases = [
        (
            "pf",
            "CW 6",
            f"N={args.particles}",
            5e-3,
            RegularisedParticleFilter(cw, n_particles=args.particles, seed=args.seed),
        ),
        ("sir", "CW 6", f"N={args.particles}", None, SIRParticleFilter(cw, n_particles=args.particles, seed=args.seed)),
        (
            "cqkf",
            "CW+bias 9",
            f"n'={args.order}, {2 * 9 * args.order} pts",
            300e-6,
            CubatureQuadratureKF(cw_bias, order=args.order),
        ),
        (
            "cqkf",
            "CW 6",
            f"n'={args.order}, {2 * 6 * args.order} pts",
            None,
            CubatureQuadratureKF(cw, order=args.order),
        ),
    ]
    print(
        f"{'filter':<6} {'dynamics':<10} {'size':<18} {'median wall':>12} {'median cpu':>11} "
        f"{'p90 wall':>10} {'target':>9}  ok"
    )
    for name, dyn_name, size, target, f in cases:
        dim = len(f.dynamics.labels)
        wall, cpu, p90 = time_steps(f, dim, args.steps, args.warmup, args.seed)
        target_text = "-" if target is None else _fmt(target)
        ok = "-" if target is None else ("yes" if wall <= target else "NO")
        print(
            f"{name:<6} {dyn_name:<10} {size:<18} {_fmt(wall):>12} {_fmt(cpu):>11} {_fmt(p90):>10} "
            f"{target_text:>9}  {ok}"
        )
    print("models: bench_models.relative_dynamics CWDynamics / CWBiasDynamics, bench_models.isl.RangeAzElModel")


def _fmt(seconds: float) -> str:
    return f"{seconds * 1e3:.2f} ms" if seconds >= 1e-3 else f"{seconds * 1e6:.0f} us"


if __name__ == "__main__":
    main()
