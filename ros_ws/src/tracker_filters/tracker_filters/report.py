"""Markdown + PNG report: a list of sections, each with tables (bench next to the paper) and figures.

Figures are drawn on ``matplotlib.figure.Figure`` objects (Agg canvas, no pyplot state), so the report can be
written from any thread or a headless CI run. Scenario-specific sections come from ``SECTION_BUILDERS``
(keyed by scenario name); a scenario without a builder gets a generic table of its scalar scores.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import LogFormatter

PAPER_LEO_RADAR = {
    "source": "paper 000 (EKF vs UKF, LEO radar), Tables 2 and 3; N = 100 Monte Carlo runs",
    "notes": [
        "The text gives peaks of 34790 m (EKF) and 34300 m (UKF); Table 2 gives 35200 m and 34700 m.",
        "Table 3's raw angle RMSE (0.435 mrad) contradicts the stated 1 deg (17.5 mrad) angle noise.",
    ],
    "filters": {
        "EKF": {
            "rmse_peak_m": 35200.0, "convergence_time_s": 33.0, "band_m": [600.0, 700.0], "rmse_converged_m": 645.0,
            "axes": {"x": {"rmse_peak_m": 7600.0, "convergence_time_s": 29.0, "band_m": [300.0, 450.0]},
                     "y": {"rmse_peak_m": 8300.0, "convergence_time_s": 32.0, "band_m": [200.0, 300.0]},
                     "z": {"rmse_peak_m": 33400.0, "convergence_time_s": 32.0, "band_m": [350.0, 500.0]}},
            "radar": {"filter": {"range_m": 14.59, "azimuth_mrad": 0.068, "elevation_mrad": 0.067},
                      "measurement": {"range_m": 31.52, "azimuth_mrad": 0.435, "elevation_mrad": 0.434}},
        },
        "UKF": {
            "rmse_peak_m": 34700.0, "convergence_time_s": 33.0, "band_m": [600.0, 700.0], "rmse_converged_m": 643.0,
            "axes": {"x": {"rmse_peak_m": 7500.0, "convergence_time_s": 29.0, "band_m": [280.0, 420.0]},
                     "y": {"rmse_peak_m": 8200.0, "convergence_time_s": 33.0, "band_m": [190.0, 295.0]},
                     "z": {"rmse_peak_m": 32900.0, "convergence_time_s": 33.0, "band_m": [340.0, 490.0]}},
            "radar": {"filter": {"range_m": 14.58, "azimuth_mrad": 0.067, "elevation_mrad": 0.0669},
                      "measurement": {"range_m": 31.52, "azimuth_mrad": 0.435, "elevation_mrad": 0.434}},
        },
    },
}
"""Paper 000's published numbers, keyed like :func:`tracker_filters.metrics.score_leo`'s output."""

PAPER_TABLES = {"leo_radar": PAPER_LEO_RADAR}
"""Paper numbers per scenario, used by :func:`write_report` when no ``paper_table`` is given."""


@dataclass
class Table:
    """A Markdown table: title, header and rows of already formatted cells."""

    title: str
    header: list[str]
    rows: list[list[str]]

    def markdown(self) -> str:
        lines = [f"**{self.title}**", "", "| " + " | ".join(self.header) + " |",
                 "|" + "---|" * len(self.header)]
        lines += ["| " + " | ".join(row) + " |" for row in self.rows]
        return "\n".join(lines)


@dataclass
class Plot:
    """A PNG figure: ``draw`` fills the given matplotlib Figure."""

    filename: str
    caption: str
    draw: Callable[[Figure], None]
    size: tuple[float, float] = (9.0, 5.0)


@dataclass
class Section:
    """One report section: a heading, free text, tables and plots."""

    title: str
    text: str = ""
    tables: list[Table] = field(default_factory=list)
    plots: list[Plot] = field(default_factory=list)


def fmt(v) -> str:
    """Format a number for a table cell (4 significant digits, integers above 1000; "—" when missing)."""
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "—"
    if isinstance(v, (list, tuple)):
        cells = [fmt(x) for x in v]
        return "—" if all(c == "—" for c in cells) else "–".join(cells)
    return f"{v:.0f}" if abs(v) >= 1000 else f"{v:.4g}"


def difference(bench, paper) -> str:
    """bench − paper with the relative difference, element-wise for bands; "—" when either is missing."""
    if isinstance(paper, (list, tuple)):
        if not isinstance(bench, (list, tuple)):
            return "—"
        return " / ".join(difference(b, p) for b, p in zip(bench, paper))
    if bench is None or paper is None or not np.isfinite(bench):
        return "—"
    d = bench - paper
    rel = f" ({100.0 * d / paper:+.0f} %)" if paper else ""
    return f"{'+' if d >= 0 else '-'}{fmt(abs(d))}{rel}"


def save_plot(out_dir: Path, plot: Plot) -> Path:
    """Draw and write one plot as PNG; returns its path."""
    fig = Figure(figsize=plot.size, layout="constrained")
    FigureCanvasAgg(fig)
    plot.draw(fig)
    path = out_dir / plot.filename
    fig.savefig(path, dpi=110)
    return path


def render(out_dir: Path, sections: Sequence[Section], title: str = "Tracking bench report") -> Path:
    """Write ``report.md`` and every section's PNGs into ``out_dir``; returns the Markdown path."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    parts = [f"# {title}"]
    for sec in sections:
        parts.append(f"## {sec.title}")
        if sec.text:
            parts.append(sec.text)
        parts += [t.markdown() for t in sec.tables]
        for plot in sec.plots:
            save_plot(out_dir, plot)
            parts.append(f"![{plot.caption}]({plot.filename})\n\n*{plot.caption}*")
    path = out_dir / "report.md"
    path.write_text("\n\n".join(parts) + "\n", encoding="utf-8")
    return path


def _paper_filter(paper: Mapping | None, name: str) -> Mapping:
    """The paper's block for a bench filter name, matched case-insensitively (empty if absent)."""
    filters = (paper or {}).get("filters", {})
    return next((v for k, v in filters.items() if k.lower() == name.lower()), {})


LEO_QUANTITIES = (("rmse_peak_m", "peak [m]"), ("convergence_time_s", "convergence time [s]"),
                  ("band_m", "band [m]"))


def leo_table2(scored: Mapping, paper: Mapping | None) -> Table:
    """Paper 000 Table 2 layout: position RMSE and per-axis error, bench vs paper per filter."""
    rows = []
    for name, block in scored.items():
        ref = _paper_filter(paper, name)
        curves = [("position RMSE", block, ref)]
        curves += [(f"error {ax}", b, ref.get("axes", {}).get(ax, {})) for ax, b in block.get("axes", {}).items()]
        for label, b, r in curves:
            for key, stat in LEO_QUANTITIES:
                rows.append([label, stat, name, fmt(b.get(key)), fmt(r.get(key)), difference(b.get(key), r.get(key))])
        key = "rmse_converged_m"
        rows.append(["position RMSE", "converged [m]", name, fmt(block.get(key)), fmt(ref.get(key)),
                     difference(block.get(key), ref.get(key))])
    return Table("Table 2 — position error (bench vs paper)",
                 ["quantity", "statistic", "filter", "bench", "paper", "difference"], rows)


def leo_table3(scored: Mapping, paper: Mapping | None) -> Table:
    """Paper 000 Table 3 layout: RMSE in radar coordinates, raw measurements and each filter."""
    rows = []
    for name, block in scored.items():
        if "radar" not in block:
            continue
        ref = _paper_filter(paper, name).get("radar", {})
        for src, label in (("measurement", f"radar (raw, {name} runs)"), ("filter", name)):
            for key in ("range_m", "azimuth_mrad", "elevation_mrad"):
                b, p = block["radar"][src].get(key), ref.get(src, {}).get(key)
                rows.append([key, label, fmt(b), fmt(p), difference(b, p)])
    return Table("Table 3 — RMSE in radar coordinates (bench vs paper)",
                 ["component", "source", "bench", "paper", "difference"], rows)


def nees_table(scored: Mapping) -> Table:
    """Filter consistency: time-averaged NEES against its chi-square bounds (not reported by the papers)."""
    rows = [[name, str(b.get("runs")), fmt(b.get("nees_mean")), str(b.get("nees_dof")), fmt(b.get("nees_bounds")),
             fmt(b.get("nees_fraction_inside"))] for name, b in scored.items() if "nees_mean" in b]
    return Table("NEES consistency (95 % two-sided chi-square bounds of the run-averaged NEES)",
                 ["filter", "runs", "mean NEES", "dof", "bounds", "fraction of steps inside"], rows)


def _draw_rmse(series: Mapping, scored: Mapping, paper: Mapping | None) -> Callable[[Figure], None]:
    def draw(fig: Figure) -> None:
        ax = fig.subplots()
        for name, s in series.items():
            line, = ax.semilogy(s["t"], s["rmse"], lw=1.0, label=name)
            tc = scored.get(name, {}).get("convergence_time_s")
            if tc is not None:
                ax.axvline(s["t"][0] + tc, color=line.get_color(), ls=":", lw=1.0,
                           label=f"{name} converged ({tc:.1f} s)")
            level = _paper_filter(paper, name).get("rmse_converged_m")
            if level is not None:
                ax.axhline(level, color=line.get_color(), ls="--", lw=0.8,
                           label=f"paper {name} converged ({level:g} m)")
        ax.set(xlabel="time since first estimate [s]", ylabel="position RMSE [m]",
               title="Position RMSE over Monte Carlo runs (paper 000 eq. 35)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    return draw


def _draw_axes(series: Mapping) -> Callable[[Figure], None]:
    def draw(fig: Figure) -> None:
        labels = list(next(iter(series.values()))["axes"])
        axs = fig.subplots(len(labels), 1, sharex=True, squeeze=False)[:, 0]
        for ax, lab in zip(axs, labels):
            for name, s in series.items():
                ax.semilogy(s["t"], s["axes"][lab], lw=1.0, label=name)
            ax.set_ylabel(f"{lab} RMSE [m]")
            ax.grid(True, which="both", alpha=0.3)
        axs[0].set_title("Per-axis position error (RMSE over runs)")
        axs[0].legend()
        axs[-1].set_xlabel("time since first estimate [s]")
    return draw


def _draw_nees(series: Mapping) -> Callable[[Figure], None]:
    def draw(fig: Figure) -> None:
        axs = fig.subplots(len(series), 1, sharex=True, squeeze=False)[:, 0]
        for ax, (name, s) in zip(axs, series.items()):
            n = s["nees"]
            ax.fill_between(n["t"], n["lo"], n["hi"], color="0.8", label="95 % chi-square band")
            ax.semilogy(n["t"], n["mean"], lw=1.0, label=f"{name} average NEES")
            ax.axhline(n["dof"], color="k", ls="--", lw=0.8, label=f"dof = {n['dof']}")
            ax.yaxis.set_major_formatter(LogFormatter())
            ax.yaxis.set_minor_formatter(LogFormatter(labelOnlyBase=False))
            ax.set_ylabel("NEES")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(loc="upper right")
        axs[0].set_title("Run-averaged NEES vs time")
        axs[-1].set_xlabel("time since first estimate [s]")
    return draw


def leo_sections(scenario: str, scored: Mapping, series: Mapping | None, paper: Mapping | None) -> list[Section]:
    """Sections for ``leo_radar``: Tables 2 and 3 side by side with the paper, NEES table, three figures."""
    text = ""
    if paper:
        text = f"Paper: {paper.get('source', '')}.\n\n" + "\n".join(f"- {n}" for n in paper.get("notes", []))
    tables = [leo_table2(scored, paper), nees_table(scored)]
    if any("radar" in b for b in scored.values()):
        tables.insert(1, leo_table3(scored, paper))
    plots = []
    if series:
        plots = [Plot(f"{scenario}_rmse.png", "Position RMSE vs time (log scale)", _draw_rmse(series, scored, paper)),
                 Plot(f"{scenario}_axes.png", "Per-axis error vs time", _draw_axes(series), (9.0, 7.0)),
                 Plot(f"{scenario}_nees.png", "NEES vs time with the chi-square band", _draw_nees(series),
                      (9.0, 2.5 + 2.5 * len(series)))]
    return [Section(scenario, text, tables, plots)]


def _flatten(block: Mapping, prefix: str = "") -> dict[str, object]:
    """Nested score dict -> {"a.b.c": value} for the scalar and band leaves."""
    out = {}
    for k, v in block.items():
        key = f"{prefix}{k}"
        if isinstance(v, Mapping):
            out.update(_flatten(v, key + "."))
        else:
            out[key] = v
    return out


def generic_sections(scenario: str, scored: Mapping, series: Mapping | None, paper: Mapping | None) -> list[Section]:
    """Fallback section: every scalar score, one column per filter."""
    flat = {name: _flatten(b) for name, b in scored.items()}
    keys = list(dict.fromkeys(k for f in flat.values() for k in f))
    rows = [[k] + [fmt(f.get(k)) if not isinstance(f.get(k), str) else f[k] for f in flat.values()] for k in keys]
    return [Section(scenario, tables=[Table("Scores", ["metric"] + list(flat), rows)])]


SectionBuilder = Callable[[str, Mapping, Mapping | None, Mapping | None], list[Section]]
SECTION_BUILDERS: dict[str, SectionBuilder] = {"leo_radar": leo_sections}
"""Per-scenario section builders (scenario, scored, series, paper) -> sections; others use the generic one."""


def write_report(out_dir: Path | str, scored: Mapping, series: Mapping, paper_table: Mapping | None = None,
                 extra_sections: Sequence[Section] = ()) -> Path:
    """Write ``report.md`` and its PNGs into ``out_dir``; returns the Markdown path.

    ``scored``: {scenario: {filter: score block}} (e.g. {"leo_radar": score_leo(...)});
    ``series``: {scenario: {filter: time series}} (e.g. {"leo_radar": leo_series(...)}), may lack scenarios;
    ``paper_table``: {scenario: paper numbers}; None uses ``PAPER_TABLES`` (pass {} for no paper columns).
    ``extra_sections`` are appended after the scenario sections.
    """
    papers = PAPER_TABLES if paper_table is None else paper_table
    sections = []
    for scenario, block in scored.items():
        builder = SECTION_BUILDERS.get(scenario, generic_sections)
        sections += builder(scenario, block, series.get(scenario), papers.get(scenario))
    return render(Path(out_dir), sections + list(extra_sections))
