#!/usr/bin/env python3
"""Lost-in-space identification benchmark: the bench's Pyramid (star_tracker.pyramid) and tetra3rs (PyPI, an
independent Rust solver; star_tracker.crosscheck) on identical frames.

Frames: uniformly random attitudes; the catalogue stars in view (star_tracker.catalogue, magnitude-limited
Hipparcos) with Gaussian centroid noise σ px per axis, detected with probability P_D, plus a number of false
stars per frame at uniform positions with magnitudes uniform in [2, 6] (so that they compete with the real
stars for the brightest places). Both solvers get the same centroids and magnitudes.

Per solver it prints:
  frames correctly identified   valid attitude reported and every identified centroid is its true star
  star identification rate      true stars identified correctly / true stars in all frames
  wrong attitudes reported valid  valid but a centroid misidentified or the attitude off by > 300"
  failures                      frames with no attitude (a failure with its reason, not a guess)
  median / p90 ms per frame     wall time of the identify call, in this process
and, on the frames both solved, whether they gave the same identities to the centroids they both identified,
and the ratio of the median times.

With ``--tracking N`` it also runs the per-frame core (star_tracker.pipeline) after the first fix: an N-frame
sequence at 10 frames/s of a camera fixed in LVLH on the 30°/700 km orbit (zenith boresight: straight drift;
``--boresight normal``: rotation about the boresight) with boresight jitter ±J °/s held for 10 frames, the
same noise, P_D and false stars, through SNA and JPDAF (constant velocity for the drift, coordinated turn for
the rotation; ``--aid``) × TRIAD and all-star (Wahba) attitude on identical frames, and prints per configuration the
median and p90 ms per frame, the frames solved, the lost-in-space
re-acquisitions, the misidentified centroids, the RMS attitude error (arcsec) and the JPDAF's filter restarts
(pipeline step 3).

Nothing is asserted (tests/test_star_*.py do that); on a shared machine the times are upper bounds.

Example:
  .venv/bin/python scripts/bench_star_id.py --frames 2000
  .venv/bin/python scripts/bench_star_id.py --frames 500 --sigma 0.5 --false-stars 5 --p-detect 0.9
  .venv/bin/python scripts/bench_star_id.py --frames 200 --tracking 400 --jitter 0.5 --p-detect 0.95
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from star_tracker.attitude import error_angle
from star_tracker.camera import Camera
from star_tracker.catalogue import ARCSEC, load_catalogue
from star_tracker.crosscheck import Tetra3Solver
from star_tracker.frames import random_attitude, simulate_frame
from star_tracker.pipeline import StarTrackerPipeline
from star_tracker.pyramid import PyramidIdentifier
from star_tracker.sky_motion import CircularOrbit, orbit_truth

WRONG_ATTITUDE = 300 * ARCSEC


def score(name: str, results: list[tuple[bool, np.ndarray, np.ndarray | None, float]], frames) -> dict:
    correct = wrong_valid = failures = stars_right = stars_total = 0
    for (ok, index, attitude, _), frame in zip(results, frames):
        real = frame.truth >= 0
        stars_total += int(real.sum())
        if not ok:
            failures += 1
            continue
        ident = index >= 0
        bad = bool(np.any(index[ident] != frame.truth[ident])) or error_angle(attitude, frame.attitude) > WRONG_ATTITUDE
        wrong_valid += bad
        correct += not bad
        stars_right += int(np.sum(index[real] == frame.truth[real]))
    ms = np.array([r[3] for r in results]) * 1e3
    n = len(frames)
    return {
        "solver": name,
        "frames": n,
        "correct_frames": correct,
        "correct_rate": correct / n,
        "star_id_rate": stars_right / max(stars_total, 1),
        "wrong_valid": wrong_valid,
        "failures": failures,
        "median_ms": float(np.median(ms)),
        "p90_ms": float(np.percentile(ms, 90)),
        "max_ms": float(ms.max()),
    }


def bench_tracking(args, catalogue, camera, identifier: PyramidIdentifier) -> dict:
    """The tracking sequence through the four pipeline configurations (module docstring)."""
    rng = np.random.default_rng(args.seed + 1)
    truth = orbit_truth(
        CircularOrbit(raan_deg=30.0, arg_latitude0_deg=50.0), args.tracking, 0.1, args.boresight, args.jitter, rng
    )
    frames = [
        simulate_frame(catalogue, camera, A, rng, sigma_px=args.sigma, p_detect=args.p_detect, n_false=args.false_stars)
        for A in truth.attitude
    ]
    density = max(args.false_stars, 0.1) / (camera.width * camera.height)
    print(
        f"tracking: {args.tracking} frames, boresight {args.boresight}, jitter ±{args.jitter} °/s, median "
        f"{np.median([len(f) for f in frames]):.0f} centroids per frame"
    )
    print(
        f"{'tracker':8s} {'solver':6s} {'median ms':>9s} {'p90 ms':>7s} {'solved':>6s} {'LIS':>4s} {'wrong IDs':>9s} "
        f"{'RMS arcsec':>10s} {'resets':>6s}"
    )
    out = {}
    for tracker in ("sna", "jpdaf"):
        for solver in ("triad", "wahba"):
            pipe = StarTrackerPipeline(
                catalogue,
                camera,
                args.sigma,
                tracker=tracker,
                solver=solver,
                p_detect=max(min(args.p_detect, 0.99), 0.5),
                clutter_density=density,
                sigma_a=args.sigma_a,
                aid=args.aid,
                identifier=identifier,
                motion="coordinated_turn" if args.boresight == "normal" else "constant_velocity",
            )
            ms, errors, lis, wrong, solved = [], [], 0, 0, 0
            for k, frame in enumerate(frames):
                t = time.perf_counter()
                j = max(k - 1, 0)
                r = pipe.process(frame.uv, frame.magnitudes, truth.t[k], truth.rate[j], truth.jitter_rate[j])
                ms.append((time.perf_counter() - t) * 1e3)
                lis += r.mode == "lost_in_space"
                if r.ok:
                    solved += 1
                    ident = r.index >= 0
                    wrong += int(np.sum(r.index[ident] != frame.truth[ident]))
                    errors.append(error_angle(r.attitude.matrix, frame.attitude) / ARCSEC)
            tracked = np.array(ms[1:]) if len(ms) > 1 else np.array(ms)
            row = {
                "median_ms": float(np.median(tracked)),
                "p90_ms": float(np.percentile(tracked, 90)),
                "solved": solved,
                "lost_in_space": lis,
                "wrong_ids": wrong,
                "filter_resets": pipe.filter_resets,
                "rms_arcsec": float(np.sqrt(np.mean(np.square(errors)))) if errors else float("nan"),
            }
            out[f"{tracker}/{solver}"] = row
            print(
                f"{tracker:8s} {solver:6s} {row['median_ms']:9.3f} {row['p90_ms']:7.3f} {solved:6d} {lis:4d} "
                f"{wrong:9d} {row['rms_arcsec']:10.3f} {pipe.filter_resets:6d}"
            )
    return out


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__
    )
    ap.add_argument("--frames", type=int, default=1000, help="random pointings (default 1000)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--sigma", type=float, default=0.2, help="centroid noise, px per axis (default 0.2)")
    ap.add_argument("--false-stars", type=int, default=2, help="false stars per frame (default 2)")
    ap.add_argument("--p-detect", type=float, default=1.0, help="probability that a star is detected")
    ap.add_argument("--fov", type=float, default=20.0, help="field of view across the width, deg")
    ap.add_argument("--pixels", type=int, default=1024, help="image width = height, px")
    ap.add_argument("--mag-limit", type=float, default=6.0)
    ap.add_argument("--cache-dir", default=None, help="catalogue and tetra3rs database cache")
    ap.add_argument("--no-tetra3", action="store_true", help="Pyramid only")
    ap.add_argument("--tracking", type=int, default=0, help="also run an N-frame tracking sequence")
    ap.add_argument("--boresight", choices=("zenith", "normal"), default="zenith")
    ap.add_argument("--jitter", type=float, default=0.5, help="boresight jitter amplitude J, °/s")
    ap.add_argument("--sigma-a", type=float, default=0.05, help="JPDAF process noise, px/s² (default 0.05)")
    ap.add_argument(
        "--aid",
        choices=("rate", "jitter", "none"),
        default="rate",
        help="how the JPDAF uses the known rate (star_tracker.pipeline; 'jitter' is the paper's)",
    )
    ap.add_argument("--json", default=None, help="also write the figures to this file")
    args = ap.parse_args()

    camera = Camera(args.fov, args.pixels, args.pixels)
    catalogue = load_catalogue(args.mag_limit, cache_dir=args.cache_dir)
    rng = np.random.default_rng(args.seed)
    frames = [
        simulate_frame(
            catalogue,
            camera,
            random_attitude(rng),
            rng,
            sigma_px=args.sigma,
            p_detect=args.p_detect,
            n_false=args.false_stars,
        )
        for _ in range(args.frames)
    ]
    print(
        f"{len(catalogue)} catalogue stars (mag <= {args.mag_limit}); camera {args.fov}° {args.pixels} px; "
        f"{args.frames} frames, median {np.median([len(f) for f in frames]):.0f} centroids, σ = {args.sigma} px, "
        f"{args.false_stars} false stars, P_D = {args.p_detect}"
    )

    solvers = {"pyramid": PyramidIdentifier(catalogue, camera, sigma_px=args.sigma)}
    if not args.no_tetra3:
        solvers["tetra3rs"] = Tetra3Solver(catalogue, camera, cache_dir=args.cache_dir)
    results = {}
    for name, solver in solvers.items():
        out = []
        call = solver.identify if name == "pyramid" else solver.solve
        for frame in frames:
            t = time.perf_counter()
            r = call(frame.uv, frame.magnitudes)
            dt = time.perf_counter() - t
            att = (r.attitude.matrix if r.ok else None) if name == "pyramid" else r.attitude
            out.append((bool(r.ok), r.index, att, dt))
        results[name] = out
    report = {name: score(name, out, frames) for name, out in results.items()}
    print(
        f"{'solver':10s} {'correct':>9s} {'star IDs':>9s} {'wrong-valid':>11s} {'failures':>8s} "
        f"{'median ms':>9s} {'p90 ms':>7s}"
    )
    for s in report.values():
        print(
            f"{s['solver']:10s} {100 * s['correct_rate']:8.2f}% {100 * s['star_id_rate']:8.3f}% "
            f"{s['wrong_valid']:11d} {s['failures']:8d} {s['median_ms']:9.3f} {s['p90_ms']:7.3f}"
        )
    if "tetra3rs" in results:
        both = agree = 0
        for (ok1, i1, _, _), (ok2, i2, _, _) in zip(results["pyramid"], results["tetra3rs"]):
            if ok1 and ok2:
                both += 1
                common = (i1 >= 0) & (i2 >= 0)
                agree += bool(np.all(i1[common] == i2[common]))
        ratio = report["pyramid"]["median_ms"] / report["tetra3rs"]["median_ms"]
        report["agreement"] = {"both_solved": both, "same_identities": agree, "median_time_ratio": ratio}
        print(
            f"agreement: same identities on {agree} of the {both} frames both solved; "
            f"median time ratio pyramid / tetra3rs = {ratio:.1f}"
        )
    if args.tracking:
        report["tracking"] = bench_tracking(args, catalogue, camera, solvers["pyramid"])
    if args.json:
        with open(args.json, "w") as f:
            json.dump(report, f, indent=2)


if __name__ == "__main__":
    main()
