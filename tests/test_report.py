"""Report writer: the claims table, Markdown tables next to the paper's numbers, PNG figures, generic and extra
sections."""

import re

import numpy as np

from bench_eval.metrics import Track, convergence_series
from bench_eval.report import Section, Table, difference, fmt, write_report
from bench_eval.study import study
from bench_studies.leo_radar.metrics import RadarSamples, score_radar_convergence

PAPER_LEO_RADAR = study("leo_radar").paper

LABELS = ["x", "y", "z", "vx", "vy", "vz"]


def leo_like_runs(n_runs, seed, floor=650.0):
    """Runs with a 35 km initial position error decaying to `floor` metres (tau 6 s), P matching the errors."""
    rng = np.random.default_rng(seed)
    t = 5000.0 + np.arange(0.0, 120.0, 0.1)
    sig_p = floor / np.sqrt(3.0) * (1.0 + 54.0 * np.exp(-(t - t[0]) / 6.0))
    sig = np.column_stack([sig_p] * 3 + [np.full(len(t), 2.0)] * 3)
    P = np.einsum("ki,ij->kij", sig**2, np.eye(6))
    runs = []
    for _ in range(n_runs):
        keep = rng.random(len(t)) < 0.95  # missed detections
        err = rng.standard_normal((keep.sum(), 6)) * sig[keep]
        runs.append(Track(t[keep], err, P[keep], np.zeros_like(err), LABELS))
    return runs


def leo_inputs():
    tracks = {"ekf": leo_like_runs(8, seed=1), "ukf": leo_like_runs(8, seed=2, floor=640.0)}
    rng = np.random.default_rng(3)
    z = np.column_stack([np.full(500, 1.5e6), rng.uniform(0, 2 * np.pi, 500), rng.uniform(0.1, 1.0, 500)])
    radar = {
        name: RadarSamples(
            z + rng.normal(size=z.shape) * [15.0, 7e-5, 7e-5], z + rng.normal(size=z.shape) * [31.6, 0.017, 0.017], z
        )
        for name in tracks
    }
    return {"leo_radar": score_radar_convergence(tracks, radar)}, {"leo_radar": convergence_series(tracks)}


def test_write_report_leo(tmp_path):
    scored, series = leo_inputs()
    path = write_report(tmp_path / "out", scored, series)
    text = path.read_text()
    assert path.name == "report.md"
    assert "| quantity | statistic | filter | bench | paper | difference |" in text
    assert "| component | source | bench | paper | difference |" in text
    assert "| position RMSE | peak [m] | ekf |" in text and "| 35200 |" in text  # paper's EKF peak
    assert "| error z | band [m] | ukf |" in text and "340–490" in text
    assert "| range_m | radar (raw, ekf runs) |" in text and "| 31.52 |" in text
    assert "34790" in text  # the text-vs-table discrepancy is reported
    # per-axis RMSE over only 8 runs still converges where sigma = 1.5 x floor: 6 ln 108 = 28.1 s
    for axis in scored["leo_radar"]["ekf"]["axes"].values():
        assert abs(axis["convergence_time_s"] - 6.0 * np.log(108.0)) < 3.0
    bench_conv = scored["leo_radar"]["ekf"]["rmse_converged_m"]
    assert (
        f"| position RMSE | converged [m] | ekf | {fmt(bench_conv)} | 645 | {difference(bench_conv, 645.0)} |" in text
    )
    for name in ("leo_radar_rmse.png", "leo_radar_axes.png", "leo_radar_nees.png"):
        png = tmp_path / "out" / name
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
        assert f"]({name})" in text


def test_report_without_paper_generic_and_extra_sections(tmp_path):
    scored, series = leo_inputs()
    scored["no_study"] = {"pf": {"runs": 2, "mae": {"x": 0.1234, "vx": 0.002}, "settling_time_s": None}}
    extra = Section("notes", "free text here", [Table("t", ["a", "b"], [["1", "2"]])])
    text = write_report(tmp_path, scored, series, paper_table={}, extra_sections=[extra]).read_text()
    assert "| 35200 |" not in text and "## no_study" in text and "## Claims" not in text
    assert "| mae.x | 0.1234 |" in text and "| settling_time_s | — |" in text
    assert text.index("## notes") > text.index("## no_study") and "| 1 | 2 |" in text


def test_formatting_helpers_and_paper_constant():
    assert difference(660.0, 645.0) == "+15 (+2 %)"
    assert difference([550.0, 720.0], [600.0, 700.0]) == "-50 (-8 %) / +20 (+3 %)"
    assert difference(None, 645.0) == "—" and fmt(float("nan")) == "—" and fmt(34712.4) == "34712"
    ekf, ukf = PAPER_LEO_RADAR["filters"]["EKF"], PAPER_LEO_RADAR["filters"]["UKF"]
    assert ekf["rmse_converged_m"] == 645.0 and ukf["rmse_converged_m"] == 643.0
    assert ukf["radar"]["filter"]["elevation_mrad"] == 0.0669
    # the per-axis peaks combine to the position peak (paper's Table 2 is internally consistent here)
    assert abs(np.linalg.norm([ekf["axes"][a]["rmse_peak_m"] for a in "xyz"]) - ekf["rmse_peak_m"]) < 100.0


def test_the_report_opens_with_the_claims_and_their_verdicts(tmp_path):
    scored, series = leo_inputs()
    text = write_report(tmp_path, scored, series).read_text()
    claims = text.index("## Claims")
    assert claims < text.index("## leo_radar")
    assert "| [leo_radar](#leo_radar) | The filters converge to a position RMSE of about 645 m" in text
    # the synthetic runs converge to ~650 m: the 8 runs decide that the claim holds
    row = next(line for line in text.splitlines() if "about 645 m" in line)
    assert row.endswith("| **holds (95 % CI vs ±15 %, 8 runs)** |")
    # their convergence time (~28 s) is under 33 s; each run's own time scatters (one EKF run converges late):
    # 8 runs decide it for the UKF only, and the verdict says how many runs the EKF's would need
    row = next(line for line in text.splitlines() if "within 33 s" in line)
    assert "| ekf: 28.1 ± 6.1 s; ukf: 28.3 ± 0.91 s |" in row
    assert re.search(
        r"\| \*\*holds for ukf; undecided for ekf \(8 runs; ~\d+ needed: 95 % CI vs the bound, 80 % power"
        r"\)\*\* \|$",
        row,
    )
    scored["leo_radar"]["ekf"]["rmse_converged_m"] = 1300.0
    scored["leo_radar"]["ekf"]["rmse_converged_m_runs"] = [1300.0, 1310.0, 1290.0]
    text = write_report(tmp_path / "b", scored, series).read_text()
    row = next(line for line in text.splitlines() if "about 645 m" in line)
    assert row.endswith("| **holds only for ukf (95 % CI vs ±15 %, 8 runs)** |")
