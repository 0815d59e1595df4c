#!/usr/bin/env python3
"""Mutation testing of the bench's core equations: does the test suite notice when an equation is wrong?

Longer than 500 lines: most of it is the table of mutations (MUTATIONS, one entry per equation), kept beside
the runner that applies it.

Each mutation is a hand-picked, plausible slip in one equation (a sign, a missing term, a transposed factor, a
check weakened), written as (file, the exact original snippet, the mutated snippet, the tests that should
catch it). For each one the script makes a scratch copy of the code (ros_ws/src, tests, scripts, pytest.ini;
never the checkout it runs from: other people run tests there), applies the mutation there, runs the listed
tests with ``pytest -x -q`` against the copy (its packages first on PYTHONPATH, ahead of the editable
installs), and reports which test caught it, or SURVIVED. The unmutated copy is run once first: if its tests
fail, no mutation result would mean anything, and the script stops.

    .venv/bin/python scripts/mutate.py                     # every mutation, then the table
    .venv/bin/python scripts/mutate.py --list              # the mutations and their tests, nothing run
    .venv/bin/python scripts/mutate.py --only kf_update_sign,pyramid_no_handedness
    .venv/bin/python scripts/mutate.py --rev HEAD          # the committed tree instead of the working tree
    .venv/bin/python scripts/mutate.py --only cubature_radius --tests tests/test_cqkf.py   # other tests

Exit status: 0 when every mutation run was caught; 1 when one survived (or its snippet is gone or ambiguous,
or its run errored); 2 on bad arguments or when the unmutated tests fail. With ``--list``: 0 when every listed
mutation can be applied here (its snippet found once, its test files present), else 1.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parent.parent
SRC = "ros_ws/src"
COPIED = ("ros_ws/src", "tests", "scripts", "pytest.ini")
SKIP = shutil.ignore_patterns("__pycache__", "*.pyc", ".pytest_cache", "build", "install", "log")
PACKAGES = tuple(yaml.safe_load((ROOT / "ros_ws" / "packages.yaml").read_text())["layers"])
"""The editable packages (ros_ws/src/PKG), lowest layer first: the copy's are put on PYTHONPATH in this order."""


@dataclass(frozen=True)
class Mutation:
    name: str
    file: str
    """Path from the repository root."""
    original: str
    """Exact text that must occur once in the file."""
    mutated: str
    tests: tuple[str, ...]
    """pytest arguments: test files or node ids, from the repository root."""
    what: str


KF = f"{SRC}/tracker_filters/tracker_filters/kf.py"
RADAR = f"{SRC}/bench_models/bench_models/radar.py"
GRACE = f"{SRC}/bench_studies/bench_studies/grace_velocity/metrics.py"
RTS = f"{SRC}/tracker_filters/tracker_filters/smoothing.py"
FIXED_LAG = f"{SRC}/tracker_filters/tracker_filters/fixed_lag.py"
PYRAMID = f"{SRC}/star_tracker/star_tracker/pyramid.py"
JPDA = f"{SRC}/star_tracker/star_tracker/jpdaf.py"
CQKF = f"{SRC}/tracker_filters/tracker_filters/cqkf.py"
CUBATURE = f"{SRC}/tracker_filters/tracker_filters/cubature.py"
PF = f"{SRC}/tracker_filters/tracker_filters/pf.py"
METRICS = f"{SRC}/bench_eval/bench_eval/metrics.py"
WINDOW = f"{SRC}/bench_eval/bench_eval/window.py"
DIFFERENTIATION = f"{SRC}/tracker_filters/tracker_filters/differentiation.py"

SMOOTHING_TESTS = (
    "tests/test_smoothing.py::test_rts_equals_the_batch_least_squares_solution",
    "tests/test_smoothing.py::test_smooth_estimates_is_rts_with_the_dynamics_transitions_between_estimates",
    "tests/test_smoothing.py::test_the_fixed_lag_smoother_equals_the_batch_map_over_its_window_and_over_the_whole_past",
    "tests/test_grace_filters.py",
)

MUTATIONS = [
    # Kalman filter (tracker_filters/kf.py): the update every linear and linearised filter shares
    Mutation(
        "kf_update_sign",
        KF,
        "return x + K.dot(nu), IKH",
        "return x - K.dot(nu), IKH",
        ("tests/test_kf_ekf_ukf.py",),
        "Kalman update moves against the innovation",
    ),
    Mutation(
        "kf_joseph_without_KRK",
        KF,
        "IKH.dot(P).dot(IKH.T) + K.dot(R).dot(K.T)",
        "IKH.dot(P).dot(IKH.T)",
        ("tests/test_kf_ekf_ukf.py",),
        "Joseph form without its K R K' term",
    ),
    Mutation(
        "kf_innovation_cov_without_R",
        KF,
        "    S += R\n",
        "    S += 0.0 * R\n",
        ("tests/test_kf_ekf_ukf.py",),
        "innovation covariance S = H P H' (R left out)",
    ),
    Mutation(
        "kf_predict_without_Q",
        KF,
        "self.P = F.dot(self.P).dot(F.T) + Q",
        "self.P = F.dot(self.P).dot(F.T)",
        ("tests/test_kf_ekf_ukf.py", "tests/test_grace_filters.py"),
        "prediction without process noise",
    ),
    # ground radar h(x) (bench_models/radar.py, paper 000 eqs. 11-14)
    Mutation(
        "radar_azimuth_from_east",
        RADAR,
        "z = [rng, math.atan2(e, n) % _TWO_PI, math.atan2(up, horiz)]",
        "z = [rng, math.atan2(n, e) % _TWO_PI, math.atan2(up, horiz)]",
        ("tests/test_radar_model.py",),
        "azimuth measured from east instead of north (single state)",
    ),
    Mutation(
        "radar_range_rate_sign",
        RADAR,
        "z.append(float(u.dot(w)) / rng)",
        "z.append(-float(u.dot(w)) / rng)",
        ("tests/test_radar_model.py",),
        "range rate of the wrong sign",
    ),
    Mutation(
        "radar_batch_elevation",
        RADAR,
        "np.arctan2(up, horiz, out=z[..., 2])",
        "np.arctan2(horiz, up, out=z[..., 2])",
        ("tests/test_radar_model.py",),
        "elevation from the zenith in the batched h (sigma points)",
    ),
    # grace_velocity's range-rate metric (paper 002 eq. 27)
    Mutation(
        "grace_residual_sign",
        GRACE,
        '"kbr": rr - z',
        '"kbr": z - rr',
        ("tests/test_grace_filters.py",),
        "residual KBR - estimate instead of estimate - KBR",
    ),
    Mutation(
        "grace_truth_residual_sign",
        GRACE,
        '"truth": rr - range_rate(truth[:, :3], truth[:, 3:])',
        '"truth": range_rate(truth[:, :3], truth[:, 3:]) - rr',
        ("tests/test_grace_filters.py",),
        "residual against the truth of the wrong sign",
    ),
    Mutation(
        "grace_nees_covariance_x4",
        GRACE,
        "np.linalg.solve(P[keep], err[..., None])",
        "np.linalg.solve(4.0 * P[keep], err[..., None])",
        ("tests/test_grace_filters.py",),
        "baseline covariance multiplied by 4 before its NEES",
    ),
    Mutation(
        "grace_range_rate_over_speed",
        GRACE,
        "np.sum(b * w, axis=-1) / np.linalg.norm(b, axis=-1)",
        "np.sum(b * w, axis=-1) / np.linalg.norm(w, axis=-1)",
        ("tests/test_grace_filters.py",),
        "b.w normalised by |w| instead of |b|",
    ),
    # RTS smoother (tracker_filters/smoothing.py) and the fixed-lag node that uses it
    Mutation(
        "rts_innovation_without_F",
        RTS,
        "return F @ x, P_pred, C",
        "return x, P_pred, C",
        SMOOTHING_TESTS,
        "smoothed mean against x_k|k, not F x_k|k",
    ),
    Mutation(
        "rts_covariance_sign",
        RTS,
        "P_s = P + C @ (P_next - P_pred) @ C.T",
        "P_s = P - C @ (P_next - P_pred) @ C.T",
        SMOOTHING_TESTS,
        "smoothed covariance correction negated",
    ),
    Mutation(
        "rts_prediction_without_Q",
        RTS,
        "P_pred = F @ P @ F.T + Q",
        "P_pred = F @ P @ F.T",
        SMOOTHING_TESTS,
        "smoother gain from a prediction without process noise",
    ),
    Mutation(
        "fixed_lag_publishes_filtered",
        FIXED_LAG,
        "list(oldest.labels),\n            x_s,\n",
        "list(oldest.labels),\n            oldest.x,\n",
        SMOOTHING_TESTS,
        "fixed-lag node publishes the filtered mean instead of the smoothed one",
    ),
    # Pyramid identification (star_tracker/pyramid.py)
    Mutation(
        "pyramid_no_handedness",
        PYRAMID,
        "tri = tri[np.sign(s_cat) == np.sign(s_obs)]",
        "tri = tri",
        ("tests/test_star_pyramid.py",),
        "handedness check of the triangle removed (mirror images pass)",
    ),
    Mutation(
        "pyramid_confirm_any_side",
        PYRAMID,
        "confirmed = (np.abs(theta.block(rows, obs_i) - cat_ang) <= self.epsilon).all(axis=1)",
        "confirmed = (np.abs(theta.block(rows, obs_i) - cat_ang) <= self.epsilon).any(axis=1)",
        ("tests/test_star_pyramid.py",),
        "4th star confirms when any side matches, not all three",
    ),
    Mutation(
        "pyramid_confirm_two_sides",
        PYRAMID,
        "confirmed = (np.abs(theta.block(rows, obs_i) - cat_ang) <= self.epsilon).all(axis=1)",
        "confirmed = (np.abs(theta.block(rows, obs_i) - cat_ang) <= self.epsilon).sum(axis=1) >= 2",
        ("tests/test_star_pyramid.py",),
        "4th star confirms when two sides of three match",
    ),
    # JPDA weights (star_tracker/jpdaf.py, the paper 003 eqs. 8-12)
    Mutation(
        "jpda_cluster_without_miss_factor",
        JPDA,
        "visit(r + 1, logw + log_miss, n_assigned)",
        "visit(r + 1, logw, n_assigned)",
        ("tests/test_star_tracking.py",),
        "joint events: a missed target costs nothing (1 - P_D P_G dropped)",
    ),
    Mutation(
        "jpda_cluster_clutter_count",
        JPDA,
        "logw + log_clutter[m - n_assigned]",
        "logw + log_clutter[n_assigned]",
        ("tests/test_star_tracking.py",),
        "clutter factor of the assigned count, not the left-over count",
    ),
    Mutation(
        "jpda_singleton_volume",
        JPDA,
        "log_pair = log_det + (log_v - np.log(m))[own]",
        "log_pair = log_det + log_v[own]",
        ("tests/test_star_tracking.py",),
        "single-target weights: V instead of V/m for a detection",
    ),
    Mutation(
        "jpda_singleton_clutter_density",
        JPDA,
        "log_pair = log_det - np.log(max(self.clutter_density, TINY_DENSITY))",
        "log_pair = log_det + np.log(max(self.clutter_density, TINY_DENSITY))",
        ("tests/test_star_tracking.py",),
        "single-target weights: lambda instead of 1/lambda",
    ),
    # CQKF points (tracker_filters/cubature.py, cqkf.py; paper 004)
    Mutation(
        "cqkf_points_transposed_factor",
        CQKF,
        "return self.x + self._xi.dot(S.T)",
        "return self.x + self._xi.dot(S)",
        ("tests/test_cqkf.py",),
        "points x + S' xi: the transposed Cholesky factor",
    ),
    Mutation(
        "cubature_radius",
        CUBATURE,
        "np.sqrt(2.0 * nodes)",
        "np.sqrt(nodes)",
        ("tests/test_cqkf.py",),
        "radial points sqrt(lambda) instead of sqrt(2 lambda)",
    ),
    Mutation(
        "cubature_weights",
        CUBATURE,
        "radial_weights / (2.0 * n * gamma(n / 2.0))",
        "radial_weights / (2.0 * n)",
        ("tests/test_cqkf.py",),
        "weights without the 1/Gamma(n/2) normalisation",
    ),
    Mutation(
        "cqkf_update_half_gain_term",
        CQKF,
        "self.P = self.P - K.dot(P_yy).dot(K.T)",
        "self.P = self.P - 0.5 * K.dot(P_yy).dot(K.T)",
        ("tests/test_cqkf.py",),
        "CQKF covariance update halved",
    ),
    # SIR particle filter (tracker_filters/pf.py)
    Mutation(
        "sir_without_process_noise",
        PF,
        "noise = sampling_factor(Q) @ self._rng.standard_normal(self._cols.shape)",
        "noise = 0.0 * sampling_factor(Q) @ self._rng.standard_normal(self._cols.shape)",
        ("tests/test_pf.py",),
        "SIR prediction without its draw of Q",
    ),
    # effective samples of a NEES time average (bench_eval/metrics.py, BDA3 section 11.5)
    Mutation(
        "ess_without_between_runs",
        METRICS,
        "var_plus = within * (n - 1) / n + (float(np.var(means, ddof=1)) if len(x) > 1 else 0.0)",
        "var_plus = within * (n - 1) / n",
        ("tests/test_metrics.py",),
        "effective samples blind to the spread of the runs' means",
    ),
    Mutation(
        "ess_counts_every_step",
        METRICS,
        "return total / max(tau, 1.0)",
        "return float(total)",
        ("tests/test_metrics.py",),
        "effective samples count every step",
    ),
    # the scoring window (bench_eval/window.py) and Savitzky-Golay's weights (issue 28)
    Mutation(
        "window_each_own_steps",
        WINDOW,
        "_rows(estimates[name], np.isin(estimates[name].steps, common))",
        "_rows(estimates[name], _finite(estimates[name]))",
        ("tests/test_scoring_window.py",),
        "each estimator scored over its own steps of the window, not the common ones",
    ),
    Mutation(
        "savgol_unscaled_slope",
        DIFFERENTIATION,
        "legendre.legval((np.asarray(at, dtype=float) - half) / half, basis_slope).T / half",
        "legendre.legval((np.asarray(at, dtype=float) - half) / half, basis_slope).T",
        ("tests/test_grace_filters.py",),
        "Savitzky-Golay slope without du/dk (the window's half-width)",
    ),
]


def _fail(message: str, status: int = 2) -> SystemExit:
    print(f"mutate.py: error: {message}", file=sys.stderr)
    return SystemExit(status)


def _parse(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(
        description=__doc__,
        epilog="Mutations: " + ", ".join(m.name for m in MUTATIONS),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--list", action="store_true", help="list the mutations and their tests, run nothing")
    p.add_argument("--only", metavar="NAME[,NAME…]", help="run only these mutations (comma-separated names)")
    p.add_argument(
        "--tests",
        nargs="+",
        metavar="TEST",
        help="run these pytest arguments (files, node ids) for every chosen mutation instead of each "
        "one's own list: does this one test catch them?",
    )
    p.add_argument(
        "--rev",
        metavar="REV",
        help="mutate this git revision (git archive) instead of the working tree. Its components are "
        "registered by this checkout's installed metadata (make setup), so a revision whose entry "
        "points differ may fail its unmutated run; pass --tests to leave such tests out",
    )
    p.add_argument(
        "--timeout",
        type=float,
        default=900.0,
        metavar="S",
        help="seconds one mutation's tests may take (default 900); past it the run counts as caught "
        "(TIMEOUT: a hang fails a test suite too)",
    )
    p.add_argument("--keep", action="store_true", help="keep the scratch directory (its path is printed)")
    return p.parse_args(argv)


def _selected(only: str | None) -> list[Mutation]:
    if not only:
        return list(MUTATIONS)
    names = [n.strip() for n in only.split(",") if n.strip()]
    known = {m.name: m for m in MUTATIONS}
    unknown = [n for n in names if n not in known]
    if unknown:
        raise _fail(f"unknown mutation(s) {', '.join(unknown)}; --list shows them")
    return [known[n] for n in names]


def _copy_tree(dest: Path, rev: str | None) -> None:
    """The code under test into ``dest``: the working tree's files, or those of git revision ``rev``."""
    dest.mkdir(parents=True)
    if rev is None:
        for rel in COPIED:
            src = ROOT / rel
            if src.is_dir():
                shutil.copytree(src, dest / rel, ignore=SKIP)
            elif src.is_file():
                shutil.copy2(src, dest / rel)
        return
    archive = subprocess.run(
        ["git", "-C", str(ROOT), "archive", "--format=tar", rev, *COPIED], capture_output=True, check=False
    )
    if archive.returncode != 0:
        raise _fail(f"git archive {rev} failed: {archive.stderr.decode().strip()}")
    subprocess.run(["tar", "-x", "-C", str(dest)], input=archive.stdout, check=True)


def _environment(tree: Path) -> dict[str, str]:
    paths = [str(tree / SRC / pkg) for pkg in PACKAGES]
    old = os.environ.get("PYTHONPATH")
    return dict(
        os.environ,
        PYTHONPATH=os.pathsep.join(paths + ([old] if old else [])),
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
        OPENBLAS_NUM_THREADS="1",
    )


def _check_imports(tree: Path, env: dict[str, str]) -> None:
    """The copy's packages, not the checkout's, must be the ones imported."""
    code = "import importlib, sys\nfor p in sys.argv[1:]:\n    print(importlib.import_module(p).__file__)"
    out = subprocess.run(
        [sys.executable, "-c", code, *PACKAGES], capture_output=True, text=True, env=env, cwd=tree, check=False
    )
    files = out.stdout.split()
    if out.returncode != 0 or len(files) != len(PACKAGES) or not all(Path(f).is_relative_to(tree) for f in files):
        raise _fail(f"the scratch copy's packages are not the ones imported:\n{out.stdout}{out.stderr}")


def _pytest(tree: Path, env: dict[str, str], tests: tuple[str, ...], timeout: float) -> tuple[int | None, str]:
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *tests]
    try:
        res = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True, timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        return None, ""
    return res.returncode, res.stdout + res.stderr


def _first_failure(output: str) -> str:
    for line in output.splitlines():
        if line.startswith(("FAILED ", "ERROR ")):
            return line.split(" ", 1)[1].split(" - ", 1)[0].strip()
    return "?"


def _apply(path: Path, m: Mutation) -> str | None:
    """Apply ``m`` to ``path``; the reason it cannot be applied, or None."""
    text = path.read_text()
    count = text.count(m.original)
    if count != 1:
        return f"snippet found {count} times in {m.file}"
    path.write_text(text.replace(m.original, m.mutated))
    return None


def main(argv: list[str] | None = None) -> int:
    args = _parse(argv)
    chosen = _selected(args.only)
    if args.tests:
        chosen = [replace(m, tests=tuple(args.tests)) for m in chosen]
    if args.list:
        applicable = True
        for m in chosen:
            count = (ROOT / m.file).read_text().count(m.original) if (ROOT / m.file).is_file() else 0
            missing = [t for t in m.tests if not (ROOT / t.split("::")[0]).is_file()]
            state = "" if count == 1 else f"  [cannot apply here: snippet found {count} times]"
            state += f"  [no test file {', '.join(missing)}]" if missing else ""
            applicable &= not state
            print(
                f"{m.name}{state}\n    {m.file}: {m.what}\n    - {m.original.strip()}\n"
                f"    + {m.mutated.strip()}\n    tests: {' '.join(m.tests)}"
            )
        return 0 if applicable else 1
    scratch = Path(tempfile.mkdtemp(prefix="bench-mutate-"))
    try:
        pristine = scratch / "pristine"
        _copy_tree(pristine, args.rev)
        env = _environment(pristine)
        _check_imports(pristine, env)
        tests = tuple(dict.fromkeys(t for m in chosen for t in m.tests))
        print(
            f"scratch copy: {pristine} ({args.rev or 'working tree'}); unmutated run of {len(tests)} test "
            f"selections ...",
            flush=True,
        )
        start = time.monotonic()
        rc, output = _pytest(pristine, env, tests, args.timeout * 2)
        if rc != 0:
            print(output[-4000:] if rc is not None else "(timed out)")
            raise _fail(f"the unmutated tests fail (pytest exit {rc}): fix them first")
        print(f"  passed in {time.monotonic() - start:.0f} s\n", flush=True)
        rows, failed = [], 0
        width = max(len(m.name) for m in chosen)
        print(f"{'mutation':<{width}}  {'result':<10}  {'seconds':>7}  caught by / note", flush=True)
        for i, m in enumerate(chosen):
            tree = scratch / f"m{i:02d}"
            shutil.copytree(pristine, tree)  # the pristine copy's bytecode stays valid: mtimes kept
            start = time.monotonic()
            problem = _apply(tree / m.file, m)
            if problem is not None:
                result, note = "ERROR", problem
            else:
                rc, output = _pytest(tree, _environment(tree), m.tests, args.timeout)
                if rc is None:
                    result, note = "TIMEOUT", f"tests ran past {args.timeout:.0f} s (counted as caught)"
                elif rc == 1:
                    result, note = "caught", _first_failure(output)
                elif rc == 0:
                    result, note = "SURVIVED", m.what
                else:
                    result, note = "ERROR", f"pytest exit {rc}: " + (output.strip().splitlines() or ["?"])[-1]
            seconds = time.monotonic() - start
            failed += result not in ("caught", "TIMEOUT")
            rows.append((m.name, result, seconds, note))
            print(f"{m.name:<{width}}  {result:<10}  {seconds:7.1f}  {note}", flush=True)
            shutil.rmtree(tree, ignore_errors=True)
        caught = sum(r[1] in ("caught", "TIMEOUT") for r in rows)
        print(f"\n{caught} of {len(rows)} mutations caught" + ("" if failed == 0 else f"; {failed} not"))
        return 0 if failed == 0 else 1
    finally:
        if args.keep:
            print(f"scratch kept: {scratch}")
        else:
            shutil.rmtree(scratch, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
