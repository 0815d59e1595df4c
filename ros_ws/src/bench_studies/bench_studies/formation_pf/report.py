"""The formation_pf report section: paper 001's claim per filter, error statistics and the particle
filters' health, with "diverged" where a filter lost the target instead of a raw metric dump."""

from __future__ import annotations

from collections.abc import Mapping

from bench_eval.claims import diverged
from bench_eval.report import Plot, Section, Table, bounds_table, draw_errors_vs_sigma, fmt, paper_note

AXES = (("x", "m"), ("y", "m"), ("z", "m"), ("vx", "m/s"), ("vy", "m/s"), ("vz", "m/s"))
COMPONENTS = tuple((axis, axis, unit, 1.0) for axis, unit in AXES)
"""Plotted components: score key, symbol, unit, factor from SI."""


def _row(name: str, block: Mapping) -> list[str]:
    runs = block.get("below_after_runs") or []
    claim = f"{sum(runs)}/{len(runs)} runs" if runs else "—"
    if diverged(block):
        return [name, str(block.get("runs")), claim, "never", "diverged"] + ["diverged"] * len(AXES)
    settle = block.get("settling_time_s")
    nees = f"{fmt(block.get('nees_mean'))} (band {fmt(block.get('nees_bounds'))})"
    return [name, str(block.get("runs")), claim, "never" if settle is None else f"{settle:.0f} s", nees] + [
        fmt(block["mae"].get(axis)) for axis, _ in AXES
    ]


def formation_pf_sections(
    scenario: str, scored: Mapping, series: Mapping | None, paper: Mapping | None
) -> list[Section]:
    """One table: per filter the runs meeting the paper's claim, settling time, NEES (or "diverged") and the
    mean absolute error per axis; the error-vs-3-sigma figure of the errors family when its series exist."""
    text = (
        "Paper 001's claim: every position axis below 0.5 m and every velocity axis below 0.02 m/s after "
        "about 80 s. 'claim met' counts the runs in which the thresholds hold from 80 s on; a filter whose "
        "normalised error is astronomically large has lost the target and is marked diverged."
    )
    if paper:
        text += "\n\n" + paper_note(paper)
    header = ["filter", "runs", "claim met", "settled (RMSE over runs)", "mean NEES (95 % band)"] + [
        f"MAE {axis} [{unit}]" for axis, unit in AXES
    ]
    table = Table(
        "Claim and errors per filter (axes: LVLH x radial, y along-track, z normal)",
        header,
        [_row(name, block) for name, block in scored.items()],
    )
    healthy = {n: s for n, s in (series or {}).items() if n in scored and not diverged(scored[n])}
    plots = (
        [
            Plot(
                f"{scenario}_errors.png",
                "Error RMSE over runs against the filters' 3σ (filters that did not diverge)",
                draw_errors_vs_sigma(healthy, scenario, COMPONENTS),
                (11.0, 6.0),
            )
        ]
        if healthy
        else []
    )
    bounds = bounds_table({n: b for n, b in scored.items() if not diverged(b)})
    return [Section(scenario, text, [table] + ([bounds] if bounds else []), plots)]
