"""The grace_velocity report section: paper 002's Table 1 next to the bench's, per estimator, with the
residual against the truth (which the paper could not measure) and the residuals over the day."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from bench_eval.report import BOUND_STYLE, Plot, Section, Table, bounds_table, fmt, paper_note, render
from bench_eval.study import load_paper
from bench_eval.sweep import sweep_intro

PAPER, CLAIMS = load_paper(Path(__file__).with_name("paper.yaml"))
MM = 1.0e3
"""m/s -> mm/s."""
BASELINE_AXES = tuple((axis, "mm", MM) for axis in ("bx", "by", "bz")) + tuple(
    (axis, "mm/s", MM) for axis in ("bvx", "bvy", "bvz")
)
"""The baseline's components in the bounds table (bench_eval.report.bounds_table groups): bound (b) is per axis."""


def _mm(v) -> str:
    return fmt(None if v is None else v * MM)


def _row(name: str, block: Mapping) -> list[str]:
    kbr, truth = block["rr_kbr"], block["rr_truth"]
    nees = block.get("baseline_nees")
    nees_cell = "—" if nees is None else f"{fmt(nees)} [{fmt(block['baseline_nees_bounds'])}]"
    return (
        [name, str(block["runs"])]
        + [_mm(kbr[s]) for s in ("std", "mean", "max", "min")]
        + [_mm(truth["std"]), _mm(truth["mean"]), _mm(block["velocity_rmse"]), nees_cell]
    )


def _paper_rows(paper: Mapping) -> list[list[str]]:
    rows = []
    for row, numbers in (paper.get("table1") or {}).items():
        method = (paper.get("methods") or {}).get(row, row)
        rows.append(
            [f"paper: {row} ({method})", "1 day"] + [_mm(numbers[s]) for s in ("std", "mean", "max", "min")] + ["—"] * 4
        )
    return rows


def _edges_table(scored: Mapping) -> Table | None:
    """Each estimator's range-rate RMS against the truth over the arc's head, the scoring window and the tail
    (bench_eval.window: the edges are scored apart, each estimator over its own steps there), or None."""
    rows = [
        [
            name,
            _mm(block["edges"].get("head", {}).get("rr_truth", {}).get("rms")),
            _mm(block["rr_truth"]["rms"]),
            _mm(block["edges"].get("tail", {}).get("rr_truth", {}).get("rms")),
        ]
        for name, block in scored.items()
        if "rr_truth" in block and block.get("edges")
    ]
    if not rows:
        return None
    return Table(
        "The arc's edges, not scored above: range-rate RMS against the truth [mm/s] over the arc's first "
        "margin (head: a causal filter's start-up, a smoother's or a fit's data on one side only), the "
        "scored window, and its last margin (tail)",
        ["estimator", "head", "window", "tail"],
        rows,
    )


def rolling_rms(t: np.ndarray, x: np.ndarray, window_s: float) -> tuple[np.ndarray, np.ndarray]:
    """RMS of x over consecutive windows of ``window_s`` seconds: (window centres, values)."""
    bins = np.floor((t - t[0]) / window_s).astype(int)
    sums, counts = np.bincount(bins, x * x), np.bincount(bins)
    keep = counts > 0
    return t[0] + (np.flatnonzero(keep) + 0.5) * window_s, np.sqrt(sums[keep] / counts[keep])


def _draw_residuals(series: Mapping):
    def draw(fig: Figure) -> None:
        top, bottom = fig.subplots(2, 1)
        for name, s in series.items():
            t, r = np.asarray(s["t"]), np.asarray(s["kbr"])
            tc, rms = rolling_rms(t, r, 1800.0)
            top.plot(tc / 3600.0, rms * MM, lw=1.0, marker=".", ms=3, label=name)
            zoom = t <= t[0] + 3 * 3600.0
            bottom.plot(t[zoom] / 3600.0, r[zoom] * MM, lw=0.6, label=name)
        # the bounds on the range rate (the same for every estimator): against the truth, so below the KBR's noise
        bounds = next((s["rr_bounds"] for s in series.values() if s.get("rr_bounds")), {})
        for name, b in bounds.items():
            tc, rms = rolling_rms(np.asarray(b["t"]), np.asarray(b["sd"]), 1800.0)
            top.plot(tc / 3600.0, rms * MM, **BOUND_STYLE, label=f"√{name} (vs truth)")
        top.set_yscale("log")
        top.set_ylabel("RMS over 30 min [mm/s]")
        top.set_xlabel("time [h]")
        bottom.set_ylabel("estimate − KBR [mm/s]")
        bottom.set_xlabel("time [h] from the arc's start (the scored day's first 3 h)")
        for ax in (top, bottom):
            ax.grid(True, which="both", alpha=0.3)
        top.legend(fontsize=7, ncol=4)

    return draw


def grace_velocity_sections(
    scenario: str, scored: Mapping, series: Mapping | None, paper: Mapping | None
) -> list[Section]:
    """Table 1 (bench next to the paper) and the residuals over the day."""
    floor = next((b.get("kbr_noise_std") for b in scored.values()), None)
    text = (
        "Range rate from each estimator's baseline (paper 002 eq. 27: ρ̇ = Δr·Δv/|Δr|) minus the KBR range "
        "rate, in mm/s, over the scenario's scoring window (the central day of an arc simulated with margins "
        "before and after it; every estimator over the same steps). The KBR's own noise (std "
        f"{_mm(floor)} mm/s here) is the "
        "floor of any residual against it; 'vs truth' removes it. Estimators: kf_a / kf_b the white-jerk "
        "Kalman filter on GNSS baselines without / with Newton velocities (variants a, b), *_lag its fixed-lag "
        "smoothing inside the graph, *_rts its fixed-interval smoothing over the run, newton / savgol numerical "
        "differentiation of the same baselines, kf_pair the difference of the filters run on each satellite; "
        "with variant 'dynamic' (like-for-like tuning on another seed), kf_a_q_rts the RTS smoothing of the "
        "filter run with its own q, orbit_fit / orbit_fit_j2 dynamic orbit determination of each satellite "
        "from its own fixes with the truth's force model / two-body + J2 and empirical accelerations "
        "(scripts/grace_bounds.py prints them next to the bounds)."
        "\n\nWhy the filter loses here (docs/studies/grace_velocity.md): in ECI the baseline turns with the "
        "orbit, so its jerk (n³|b| ≈ 3e-4 m/s³) forces a large white-jerk q, which passes GNSS noise into the "
        "velocity along the baseline, the only component the range rate sees."
    )
    if paper:
        text += "\n\n" + paper_note(paper)
    header = [
        "estimator",
        "runs",
        "std",
        "mean",
        "max",
        "min",
        "std vs truth",
        "mean vs truth",
        "velocity RMSE (3D)",
        "baseline NEES, 6 dof [95 % band of its effective samples]",
    ]
    rows = [_row(n, b) for n, b in scored.items() if "rr_kbr" in b] + _paper_rows(paper or {})
    table = Table("Range-rate residual against the KBR [mm/s] (Table 1), and against the truth", header, rows)
    edges = _edges_table(scored)
    # the baseline against bound (b) axis by axis (the bound's groups), where the scenario scores it (variant dynamic)
    bounds = bounds_table(scored, BASELINE_AXES)
    plots = (
        [
            Plot(
                f"{scenario}_residuals.png",
                "Range-rate residual against the KBR (first run): its RMS over "
                "30-minute windows through the scored day, and the residual itself over its first three hours",
                _draw_residuals(series),
                (11.0, 7.0),
            )
        ]
        if series
        else []
    )
    return [Section(scenario, text, [table] + ([edges] if edges else []) + ([bounds] if bounds else []), plots)]


SWEEP_ORDER = ("kf_a", "kf_b", "kf_a_lag", "kf_a_rts", "newton", "savgol")


def _cell_axes(cell: Mapping) -> tuple[float, float]:
    """(fix interval [s], GNSS sigma [m]) of a sweep cell, from its overrides."""
    values = dict(o.split("=", 1) for o in cell["overrides"])
    return float(values["sensors.gnss1.interval"]), float(values["sensors.gnss1.sigma_position"])


def _methods(cells: list) -> list[str]:
    present = set().union(*(c["score"]["estimators"] for c in cells if c.get("score")))
    return [m for m in SWEEP_ORDER if m in present] + sorted(present - set(SWEEP_ORDER))


def _std_cell(block: Mapping | None) -> str:
    if not block:
        return "—"
    runs = block["rr_kbr_runs"]["std"]
    spread = f" ± {np.std(runs, ddof=1) / np.sqrt(len(runs)) * MM:.2g}" if len(runs) > 1 else ""
    return f"{block['rr_kbr']['std'] * MM:.3g}{spread}"


def sweep_tables(sweep: Mapping) -> list[Table]:
    """Per cell (interval x sigma): each method's residual std (mean ± standard error over runs), its mean
    (bias) and the winner."""
    cells = [c for c in sweep["cells"] if c.get("score")]
    methods = _methods(cells)
    rows_std, rows_mean = [], []
    for cell in sorted(cells, key=_cell_axes):
        interval, sigma = _cell_axes(cell)
        scores = cell["score"]["estimators"]
        best = min((m for m in methods if m in scores), key=lambda m: scores[m]["rr_kbr"]["std"])
        label = [f"{interval:g} s", f"{sigma * 100:g} cm"]
        rows_std.append(label + [_std_cell(scores.get(m)) for m in methods] + [best])
        rows_mean.append(label + [_mm(scores[m]["rr_kbr"]["mean"]) if m in scores else "—" for m in methods])
    head = ["fix interval", "GNSS σ"]
    return [
        Table(
            "Range-rate residual std against the KBR [mm/s], mean ± standard error over the runs",
            head + list(methods) + ["best"],
            rows_std,
        ),
        Table("Mean range-rate residual (bias) [mm/s]", head + list(methods), rows_mean),
    ]


def _draw_sweep(sweep: Mapping):
    cells = [c for c in sweep["cells"] if c.get("score")]
    methods = _methods(cells)
    sigmas = sorted({_cell_axes(c)[1] for c in cells})

    def draw(fig: Figure) -> None:
        axs = fig.subplots(1, len(sigmas), sharey=True, squeeze=False)[0]
        for ax, sigma in zip(axs, sigmas):
            row = sorted((c for c in cells if _cell_axes(c)[1] == sigma), key=_cell_axes)
            x = [_cell_axes(c)[0] for c in row]
            for m in methods:
                y = [c["score"]["estimators"].get(m, {}).get("rr_kbr", {}).get("std", np.nan) * MM for c in row]
                ax.plot(x, y, marker="o", ms=3, lw=1.0, label=m)
            ax.set_yscale("log")
            ax.set_xlabel("GNSS fix interval [s]")
            ax.set_title(f"σ = {sigma * 100:g} cm per axis")
            ax.grid(True, which="both", alpha=0.3)
        axs[0].set_ylabel("range-rate residual std [mm/s]")
        axs[0].legend(fontsize=7)

    return draw


def write_sweep_report(out_dir, sweep: Mapping, series: Mapping, extra_markdown: str = "") -> Path:
    """``table.md`` of a grace_velocity sweep (sweep.json content) with its plot; returns its path."""
    text = sweep_intro(sweep, ", one day each")
    plot = Plot(
        f"{sweep['scenario']}_{sweep['grid']}.png",
        "Range-rate residual std per method against the fix interval, one panel per GNSS noise",
        _draw_sweep(sweep),
        (12.0, 4.5),
    )
    section = Section(f"{sweep['scenario']} — sweep '{sweep['grid']}'", text, sweep_tables(sweep), [plot])
    return render(Path(out_dir), [section], f"Sweep {sweep['scenario']} / {sweep['grid']}", filename="table.md")
