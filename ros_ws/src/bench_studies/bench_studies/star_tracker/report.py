"""The star_tracker report: the run's attitude errors next to the paper's Table of the same case, the
identification and tracking figures, the attitude error per frame, and the sweep report (Tables 3–8: SNA vs
JPDAF per cell, mean ± standard error over the runs, next to the paper's)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from bench_eval.report import (
    BOUND_STYLE,
    Plot,
    Section,
    Table,
    bound_curves,
    bounds_table,
    fmt,
    paper_note,
    render,
    thin,
)
from bench_eval.study import load_paper
from bench_eval.sweep import sweep_intro
from bench_studies.star_tracker.metrics import scenario_case

PAPER, CLAIMS = load_paper(Path(__file__).with_name("paper.yaml"))
ORDER = ("sna_triad", "jpdaf_triad", "sna_wahba", "jpdaf_wahba")
SIGMA_VARIANCE = {0.1732050808: "0.03", 0.1414213562: "0.02", 0.1303840481: "0.017", 0.1: "0.01", 0.0707106781: "0.005"}
"""The camera's sigma_px (std) -> the paper's sigma read as a variance (scenario.yaml)."""


def paper_case(cfg: Mapping) -> Mapping | None:
    """The paper's numbers for a resolved scenario (:func:`paper_numbers` of its boresight, jitter and sigma)."""
    case = scenario_case(cfg)
    return paper_numbers(case["boresight"], case["jitter_deg_s"], case["sigma_px"])


def paper_numbers(boresight: str | None, jitter_deg_s: float, sigma_px: float | None) -> Mapping | None:
    """The paper's numbers for a case: motion (boresight normal: rotation, else linear), jitter and sigma (the
    camera's sigma_px read as a variance) -> the table, or None when the case is not one of the paper's."""
    motion = "rotation" if boresight == "normal" else "linear"
    jitter = f"{float(jitter_deg_s):g}"
    sigma_px = float(sigma_px or 0.0)
    sigma = next((v for k, v in SIGMA_VARIANCE.items() if abs(k - sigma_px) < 1e-6), None)
    numbers = ((PAPER.get("tables") or {}).get(motion) or {}).get(jitter, {}).get(sigma) if sigma else None
    if numbers is None:
        return None
    return {
        "table": PAPER["table_numbers"][motion][jitter],
        "motion": motion,
        "jitter_deg_s": jitter,
        "sigma": sigma,
        "sna": numbers[0],
        "jpdaf": numbers[1],
        "gain_pct": 100.0 * (numbers[0] - numbers[1]) / numbers[0],
    }


def _se(values) -> float | None:
    v = np.array([x for x in (values or []) if x is not None], dtype=float)
    return float(np.std(v, ddof=1) / np.sqrt(len(v))) if len(v) > 1 else None


def _pm(block: Mapping | None, key: str, digits: int = 3) -> str:
    if not block or block.get(key) is None:
        return "—"
    se = _se(block.get(f"{key}_runs"))
    return f"{block[key]:.{digits}g}" + (f" ± {se:.2g}" if se is not None else "")


def _names(scored: Mapping) -> list[str]:
    return [n for n in ORDER if n in scored] + sorted(set(scored) - set(ORDER))


BOUND_DASHES = [(0, (6, 2)), (0, (2, 2)), (0, (8, 2, 1, 2))]
"""One dash pattern per bound (all black, as BOUND_STYLE): the study has up to three (per frame, under the
trackers' motion model, under the truth's motion)."""


def attitude_bounds(series: Mapping) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(bound name, t, √bound of the whole attitude error [arcsec]): the square root of the sum of the three axes'
    bounds, i.e. the bound on the error rotation's angle that the estimators' RMS is drawn against."""
    axes = [{name: (t, v) for name, t, v in bound_curves(series, key)} for key, _, _ in BOUND_AXES]
    return [
        (name, t, ARCSEC * np.sqrt(sum(a[name][1] ** 2 for a in axes)))
        for name, (t, _) in axes[0].items()
        if all(name in a for a in axes)
    ]


def _draw_errors(series: Mapping):
    def draw(fig: Figure) -> None:
        ax = fig.subplots()
        for name in _names(series):
            s = series[name]
            ax.semilogy(s["t"], s["error_arcsec"], lw=0.8, label=name)
        for (name, t, values), dashes in zip(attitude_bounds(series), BOUND_DASHES):
            k = thin(t)
            ax.semilogy(t[k], values[k], label=f"√{name}", **{**BOUND_STYLE, "ls": dashes})
        ax.set_xlabel("time since the first estimate [s]")
        ax.set_ylabel("attitude error [arcsec] (RMS over runs)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)

    return draw


def star_tracker_sections(
    scenario: str, scored: Mapping, series: Mapping | None, paper: Mapping | None
) -> list[Section]:
    """The run's case next to the paper's table, and the attitude error per frame."""
    run = next((b["case"] for b in scored.values() if b.get("case")), None)
    case = paper_numbers(**run) if run else None
    text = (
        "Attitude error = angle of the error rotation (paper eq. 20), arcsec, after the first second; "
        "cross-boresight and roll are its parts; NEES over 3 dof (3 when the covariance is right). SNA and the "
        "JPDAF run side by side on identical frames (the same /camera/measurement), each with TRIAD (the paper's "
        "two-star solution) and the all-star SVD solution of Wahba's problem. Identification and per-star "
        "centroid errors are scored against the camera's own truth topic (/camera/star_truth)."
    )
    if paper:
        text += "\n\n" + paper_note(paper)
    header = [
        "estimator",
        "runs",
        "RMS [arcsec]",
        "cross-boresight",
        "roll",
        "NEES (3)",
        "solved",
        "first fix [s]",
        "ID rate",
        "false IDs / frame",
        "centroid error [arcsec]",
        "LIS / re-acq.",
        "gain vs SNA",
    ]
    rows = []
    for name in _names(scored):
        b = scored[name]
        rows.append(
            [
                name,
                str(b.get("runs", "")),
                _pm(b, "rms_arcsec"),
                fmt(b.get("cross_arcsec")),
                fmt(b.get("roll_arcsec")),
                fmt(b.get("nees")),
                fmt(b.get("solved")),
                fmt(b.get("first_fix_s")),
                fmt(b.get("identification_rate")),
                fmt(b.get("false_ids")),
                fmt(b.get("centroid_arcsec")),
                f"{fmt(b.get('lost_in_space'))} / {fmt(b.get('reacquisitions'))}",
                "—" if b.get("gain_pct") is None else f"{_pm(b, 'gain_pct', 2)} %",
            ]
        )
    if case:
        rows.append([f"paper Table {case['table']}: SNA", "—", fmt(case["sna"])] + ["—"] * 9 + ["—"])
        rows.append(
            [f"paper Table {case['table']}: JPDAF", "—", fmt(case["jpdaf"])] + ["—"] * 9 + [f"{case['gain_pct']:.1f} %"]
        )
        title = (
            f"Attitude error, {case['motion']} motion, jitter {case['jitter_deg_s']} °/s, σ = {case['sigma']} "
            f"(paper Table {case['table']})"
        )
    else:
        title = "Attitude error (this case is not one of the paper's tables)"
    plots = (
        [
            Plot(
                f"{scenario}_attitude_error.png",
                "Attitude error per frame (RMS over the runs) and each bound's square root (black dashed)",
                _draw_errors(series),
                (10.0, 4.5),
            )
        ]
        if series
        else []
    )
    bounds = bounds_table(scored, BOUND_AXES)
    return [Section(scenario, text, [Table(title, header, rows)] + ([bounds] if bounds else []), plots)]


ARCSEC = 180.0 / np.pi * 3600.0
BOUND_AXES = (("rx", "arcsec", ARCSEC), ("ry", "arcsec", ARCSEC), ("rz", "arcsec (roll)", ARCSEC))
"""The attitude error's camera-frame components in the bound table (bench_eval.report.bounds_table). The
scenario's bounds (bench_studies.star_tracker.bounds): ``wahba`` per frame, which a tracker that carries stars
across frames (JPDAF) may go below; ``wahba_tracked`` across frames under the JPDAF's motion model, which the
JPDAF may beat slightly as the truth has no residual motion; ``wahba_truth`` across frames under the truth's
motion (star_tracker.tracked_bound)."""


def sweep_tables(sweep: Mapping) -> list[Table]:
    """Per cell: SNA and JPDAF (TRIAD, then all-star) mean ± standard error over the runs, next to the paper."""
    rows = []
    for cell in sweep["cells"]:
        scores = (cell.get("score") or {}).get("estimators") or {}
        paper = cell.get("paper") or {}
        sna, jp = scores.get("sna_triad"), scores.get("jpdaf_triad")
        rows.append(
            [
                ", ".join(f"{k} {v}" for k, v in cell["labels"].items()),
                str(paper.get("sigma", "—")),
                _pm(sna, "rms_arcsec"),
                _pm(jp, "rms_arcsec"),
                _pm(jp, "gain_pct", 2),
                fmt(paper.get("sna")),
                fmt(paper.get("jpdaf")),
                "—" if not paper else f"{paper['gain_pct']:.1f}",
                _pm(scores.get("sna_wahba"), "rms_arcsec"),
                _pm(scores.get("jpdaf_wahba"), "rms_arcsec"),
                _pm(scores.get("jpdaf_wahba"), "gain_pct", 2),
            ]
        )
    header = [
        "cell",
        "σ (paper)",
        "SNA TRIAD",
        "JPDAF TRIAD",
        "gain [%]",
        "paper SNA",
        "paper JPDAF",
        "paper gain [%]",
        "SNA all-star",
        "JPDAF all-star",
        "gain all-star [%]",
    ]
    return [
        Table(
            "RMS attitude error [arcsec], mean ± standard error over the runs, next to paper Tables 3–8 "
            "(where the cell is one of the paper's cases)",
            header,
            rows,
        )
    ]


def _draw_sweep(sweep: Mapping):
    def draw(fig: Figure) -> None:
        ax = fig.subplots()
        cells = [c for c in sweep["cells"] if c.get("score") and c.get("paper")]
        for name, key, marker in (("sna_triad", "sna", "o"), ("jpdaf_triad", "jpdaf", "s")):
            bench = [c["score"]["estimators"].get(name, {}).get("rms_arcsec") or np.nan for c in cells]
            paper = [c["paper"][key] for c in cells]
            ax.plot(paper, bench, marker, label=name)
        lim = [0.0, max([1.0] + [c["paper"]["sna"] for c in cells]) * 1.2]
        ax.plot(lim, lim, "k--", lw=0.8, label="bench = paper")
        ax.set_xlabel("paper [arcsec]")
        ax.set_ylabel("bench [arcsec]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)

    return draw


def write_sweep_report(out_dir, sweep: Mapping, series: Mapping, extra_markdown: str = "") -> Path:
    """``table.md`` of a star_tracker sweep (sweep.json content) with its plot; returns its path."""
    text = sweep_intro(sweep)
    plot = Plot(
        f"{sweep['scenario']}_{sweep['grid']}.png",
        "Bench against paper, RMS attitude error per cell (TRIAD)",
        _draw_sweep(sweep),
        (6.5, 5.5),
    )
    section = Section(f"{sweep['scenario']} — sweep '{sweep['grid']}'", text, sweep_tables(sweep), [plot])
    return render(Path(out_dir), [section], f"Sweep {sweep['scenario']} / {sweep['grid']}", filename="table.md")
