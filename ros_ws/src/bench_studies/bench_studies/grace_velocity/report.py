"""The grace_velocity report section: paper 002's Table 1 next to the bench's, per estimator, with the
residual against the truth (which the paper could not measure) and the residuals over the day."""
from __future__ import annotations

from pathlib import Path
from typing import Mapping

import numpy as np
from matplotlib.figure import Figure

from bench_eval.report import Plot, Section, Table, fmt, thin
from bench_eval.study import load_paper

PAPER, CLAIMS = load_paper(Path(__file__).with_name("paper.yaml"))
MM = 1.0e3
"""m/s -> mm/s."""


def _mm(v) -> str:
    return fmt(None if v is None else v * MM)


def _row(name: str, block: Mapping) -> list[str]:
    kbr, truth = block["rr_kbr"], block["rr_truth"]
    return ([name, str(block["runs"])] + [_mm(kbr[s]) for s in ("std", "mean", "max", "min")]
            + [_mm(truth["std"]), _mm(truth["mean"]), _mm(block["velocity_rmse"])])


def _paper_rows(paper: Mapping) -> list[list[str]]:
    rows = []
    for row, numbers in (paper.get("table1") or {}).items():
        method = (paper.get("methods") or {}).get(row, row)
        rows.append([f"paper: {row} ({method})", "1 day"] + [_mm(numbers[s]) for s in ("std", "mean", "max", "min")]
                    + ["—"] * 3)
    return rows


def _draw_residuals(series: Mapping):
    def draw(fig: Figure) -> None:
        axs = fig.subplots(2, 1, sharex=True)
        for name, s in series.items():
            cut = thin(np.asarray(s["t"]))
            for ax, key in zip(axs, ("kbr", "truth")):
                ax.plot(np.asarray(s["t"])[cut] / 3600.0, np.asarray(s[key])[cut] * MM, lw=0.6, label=name)
        axs[0].set_ylabel("estimate − KBR [mm/s]")
        axs[1].set_ylabel("estimate − truth [mm/s]")
        axs[1].set_xlabel("time [h]")
        for ax in axs:
            ax.grid(True, alpha=0.3)
        axs[0].legend(fontsize=7, ncol=3)
    return draw


def grace_velocity_sections(scenario: str, scored: Mapping, series: Mapping | None,
                            paper: Mapping | None) -> list[Section]:
    """Table 1 (bench next to the paper) and the residuals over the day."""
    floor = next((b.get("kbr_noise_std") for b in scored.values()), None)
    text = ("Range rate from each estimator's baseline (paper 002 eq. 27: ρ̇ = Δr·Δv/|Δr|) minus the KBR range "
            f"rate, in mm/s, after the filters' start-up. The KBR's own noise (std {_mm(floor)} mm/s here) is the "
            "floor of any residual against it; 'vs truth' removes it. Estimators: kf_a / kf_b the white-jerk "
            "Kalman filter on GNSS baselines without / with Newton velocities (variants a, b), *_rts its "
            "fixed-interval smoothing, newton / savgol numerical differentiation of the same baselines, kf_pair "
            "the difference of the filters run on each satellite.")
    if paper:
        text += f"\n\nPaper: {paper.get('source', '')}.\n\n" + "\n".join(f"- {n}" for n in paper.get("notes", []))
    header = ["estimator", "runs", "std", "mean", "max", "min", "std vs truth", "mean vs truth",
              "velocity RMSE (3D)"]
    rows = [_row(n, b) for n, b in scored.items() if "rr_kbr" in b] + _paper_rows(paper or {})
    table = Table("Range-rate residual against the KBR [mm/s] (Table 1), and against the truth", header, rows)
    plots = [Plot(f"{scenario}_residuals.png", "Range-rate residual over the day (first run): against the KBR and "
                  "against the truth", _draw_residuals(series), (11.0, 6.0))] if series else []
    return [Section(scenario, text, [table], plots)]
