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
from matplotlib.ticker import LogFormatter, NullFormatter

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
"""Paper 000's published numbers, keyed like :func:`bench_eval.metrics.score_leo`'s output."""

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


def render(out_dir: Path, sections: Sequence[Section], title: str = "Tracking bench report",
           filename: str = "report.md") -> Path:
    """Write ``filename`` (Markdown) and every section's PNGs into ``out_dir``; returns the Markdown path."""
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
    path = out_dir / filename
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


# ------------------------------------------------------------------------------- formation_cqkf (paper 004)

FORMATION_COMPONENTS = (("x", "δx", "m", 1.0), ("y", "δy", "m", 1.0), ("z", "δz", "m", 1.0),
                        ("vx", "δvx", "mm/s", 1e3), ("vy", "δvy", "mm/s", 1e3), ("vz", "δvz", "mm/s", 1e3))
"""Formation state components: score key, paper symbol, paper unit, factor from SI to that unit."""


def _paper004(ss: Sequence[float], cw: Sequence[float], cwb: Sequence[float]) -> dict:
    keys = [c[0] for c in FORMATION_COMPONENTS]
    return {"ss": dict(zip(keys, ss)), "cw": dict(zip(keys, cw)), "cw_bias": dict(zip(keys, cwb))}


PAPER_FORMATION_CQKF = {
    "source": "paper 004 (CQKF relative navigation), Tables 1 (e = 0) and 2 (e = 0.005): mean absolute error, "
              "nonlinear measurements [alpha, epsilon, rho], 1 s sampling, one orbit",
    "notes": [
        "Positions in m, velocities in mm/s, as printed. Columns read right to left (Persian layout): "
        "SS (Schweighart-Sedwick), CW, CW+bias for rho = 1 km, then for rho = 10 km.",
        "The paper does not state its number of Monte Carlo runs, its inclination or how its sigma was tuned "
        "beyond 'errors inside +-3 sigma' (a different sigma per case).",
    ],
    "models": {"ss": "SS", "cw": "CW", "cw_bias": "CW+bias"},
    "cases": [
        {"table": 1, "e": 0.0, "rho_m": 1000.0,
         "mae": _paper004([0.036, 0.041, 0.043, 0.121, 0.132, 0.159], [0.121, 0.052, 0.066, 0.811, 0.393, 0.484],
                          [0.084, 0.049, 0.073, 0.528, 0.224, 0.284])},
        {"table": 1, "e": 0.0, "rho_m": 10000.0,
         "mae": _paper004([0.879, 0.681, 0.614, 2.64, 2.51, 3.63], [1.65, 0.52, 0.59, 11.1, 5.24, 5.52],
                          [0.871, 0.551, 0.814, 5.84, 4.07, 5.70])},
        {"table": 2, "e": 0.005, "rho_m": 1000.0,
         "mae": _paper004([0.042, 0.046, 0.055, 0.104, 0.132, 0.163], [0.111, 0.107, 0.099, 0.917, 0.678, 0.984],
                          [0.084, 0.049, 0.073, 1.008, 0.539, 0.411])},
        {"table": 2, "e": 0.005, "rho_m": 10000.0,
         "mae": _paper004([0.868, 0.449, 0.792, 2.74, 2.04, 3.33], [1.61, 1.01, 1.19, 11.2, 6.54, 7.76],
                          [1.189, 0.751, 1.065, 7.84, 5.97, 5.04])},
    ],
}
"""Paper 004's Tables 1 and 2, per case (e, relative orbit size) and dynamics model (keys of the filters'
``dynamics.model``), mean absolute error per component in the paper's units (m, mm/s)."""

PAPER_TABLES["formation_cqkf"] = PAPER_FORMATION_CQKF


def paper004_case(cfg: Mapping) -> dict | None:
    """The paper 004 table case a resolved ``formation_cqkf`` configuration reproduces, or None.

    A case needs the chief's e and the relative orbit size of the table, nonlinear (range/angles)
    measurements every 1 s and a 1 s step.
    """
    truth, sensors = cfg.get("truth") or {}, list((cfg.get("sensors") or {}).values())
    e = float((truth.get("chief") or {}).get("e", 0.0))
    size = ((truth.get("deputy") or {}).get("pco") or {}).get("size")
    radio = [s for s in sensors if isinstance(s, Mapping) and s.get("type") == "isl_radio"]
    if size is None or len(radio) != 1 or float(radio[0].get("interval", 0.0)) != 1.0 \
            or float((cfg.get("time") or {}).get("dt", 0.0)) != 1.0:
        return None
    return next((c for c in PAPER_FORMATION_CQKF["cases"]
                 if np.isclose(c["e"], e, atol=1e-9) and np.isclose(c["rho_m"], float(size))), None)


def mean_se(values: Sequence[float]) -> tuple[float, float]:
    """Mean and standard error (s / sqrt(N); NaN for one value) of per-run values."""
    v = np.asarray(values, dtype=float)
    return float(np.mean(v)), float(np.std(v, ddof=1) / np.sqrt(len(v))) if len(v) > 1 else float("nan")


def fmt_mean_se(values: Sequence[float], factor: float = 1.0) -> str:
    """"mean ± SE" of per-run values in a display unit (``factor`` from SI)."""
    m, se = mean_se(np.asarray(values, dtype=float) * factor)
    return f"{m:.3g}" if not np.isfinite(se) else f"{m:.3g} ± {se:.2g}"


def paired_ordering(mae_runs: Mapping[str, Sequence[float]], names: Mapping[str, str] | None = None,
                    alpha: float = 0.05) -> str:
    """Filters sorted by mean error, "<" where the paired difference over the same runs is significant
    (two-sided t-test at ``alpha``), "≈" where it is not (always "≈" with a single run)."""
    from scipy.stats import t as student
    order = sorted(mae_runs, key=lambda k: float(np.mean(mae_runs[k])))
    label = (lambda k: names.get(k, k)) if names else str
    text = label(order[0])
    for a, b in zip(order, order[1:]):
        d = np.asarray(mae_runs[b], dtype=float) - np.asarray(mae_runs[a], dtype=float)
        n = len(d)
        se = np.std(d, ddof=1) / np.sqrt(n) if n > 1 else 0.0
        significant = n > 1 and se > 0 and np.mean(d) / se > student.ppf(1.0 - 0.5 * alpha, n - 1)
        text += f" {'<' if significant else '≈'} {label(b)}"
    return text


def _paper_ordering(case: Mapping, models: Mapping[str, str], comp: str, names: Mapping[str, str]) -> str:
    """The paper's ordering of the bench filters (by their dynamics model) for one component."""
    values = {f: case["mae"][m][comp] for f, m in models.items() if m in case["mae"]}
    return " < ".join(names.get(f, f) for f in sorted(values, key=values.get))


def formation_mae_table(title: str, scored: Mapping, paper_case: Mapping | None, models: Mapping[str, str]) -> Table:
    """Paper 004 Tables 1-2 layout for one case: rows are components, per filter bench mean ± SE and paper."""
    names = list(scored)
    header = ["state"] + [f"{n} bench" for n in names] + ([f"{n} paper" for n in names] if paper_case else [])
    rows = []
    for key, symbol, unit, factor in FORMATION_COMPONENTS:
        row = [f"{symbol} [{unit}]"]
        row += [fmt_mean_se(scored[n].get("mae_runs", {}).get(key) or [scored[n]["mae"][key]], factor) for n in names]
        if paper_case:
            row += [fmt(paper_case["mae"].get(models.get(n, ""), {}).get(key)) for n in names]
        rows.append(row)
    return Table(title, header, rows)


def formation_consistency_table(title: str, rows_in: Sequence[tuple[str, str, Mapping, object]]) -> Table:
    """(case, filter, score block, sigma_accel) rows -> NEES and 3-sigma consistency table."""
    rows = []
    for case, name, b, sigma in rows_in:
        inside = list((b.get("within_3sigma") or {}).values())
        rows.append([case, name, fmt(sigma) if not isinstance(sigma, str) else sigma, str(b.get("runs")),
                     fmt(b.get("nees_mean")), fmt(b.get("nees_bounds")), fmt(b.get("nees_fraction_inside")),
                     f"{min(inside):.0%}–{max(inside):.0%}" if inside else "—"])
    return Table(title, ["case", "filter", "sigma_accel [m/s^1.5]", "runs", "mean NEES (6 dof)", "95 % band",
                         "steps inside band", "errors within ±3σ (per component)"], rows)


def _thin(t: np.ndarray, max_points: int = 2000) -> slice:
    return slice(None, None, max(1, len(t) // max_points))


def _draw_formation_errors(series: Mapping, title: str) -> Callable[[Figure], None]:
    """Per component: RMSE over runs (solid) and the filter's 3 sigma (dashed), one colour per filter."""
    def draw(fig: Figure) -> None:
        axs = fig.subplots(2, 3, sharex=True)
        for (key, symbol, unit, factor), ax in zip(FORMATION_COMPONENTS, axs.ravel()):
            for name, s in series.items():
                k = _thin(s["t"])
                line, = ax.semilogy(s["t"][k], factor * np.asarray(s["rmse"][key])[k], lw=0.8, label=f"{name} RMSE")
                ax.semilogy(s["t"][k], 3.0 * factor * np.asarray(s["sigma"][key])[k], lw=0.8, ls="--",
                            color=line.get_color(), label=f"{name} 3σ")
            ax.set_title(f"{symbol} [{unit}]", fontsize=9)
            ax.grid(True, which="both", alpha=0.3)
        for ax in axs[1]:
            ax.set_xlabel("time [s]")
        axs[0, 0].legend(fontsize=7)
        fig.suptitle(title, fontsize=10)
    return draw


def _filter_models(scored: Mapping) -> dict[str, str]:
    """Bench filter name -> paper 004 dynamics model key, by name (ss, cw, cwb as in the scenario)."""
    by_name = {"ss": "ss", "cw": "cw", "cwb": "cw_bias"}
    return {n: by_name[n] for n in scored if n in by_name}


def formation_cqkf_sections(scenario: str, scored: Mapping, series: Mapping | None,
                            paper: Mapping | None) -> list[Section]:
    """Sections for one ``formation_cqkf`` run or Monte Carlo (its default case e = 0, rho = 1 km, 1 s)."""
    case = next((c for c in (paper or {}).get("cases", []) if c["e"] == 0.0 and c["rho_m"] == 1000.0), None)
    text = ("Bench mean absolute error (± standard error over runs) next to paper 004 Table 1, rho = 1 km, "
            "which is the scenario's default case: the paper column does not apply to runs with variants "
            "(scripts/sweep.py compares every case of the paper's grid).")
    if paper:
        text += f"\n\nPaper: {paper.get('source', '')}.\n\n" + "\n".join(f"- {n}" for n in paper.get("notes", []))
    tables = [formation_mae_table("Mean absolute error (bench vs paper Table 1, 1 km)", scored, case,
                                  _filter_models(scored)),
              formation_consistency_table("Consistency", [("scenario as run", n, b, "—") for n, b in scored.items()])]
    plots = [Plot(f"{scenario}_errors.png", "Error RMSE over runs against the filters' 3σ (paper 004 Figs. 1-6)",
                  _draw_formation_errors(series, scenario), (11.0, 6.0))] if series else []
    return [Section(scenario, text, tables, plots)]


SECTION_BUILDERS["formation_cqkf"] = formation_cqkf_sections


# ------------------------------------------------------------------- sweeps (scripts/sweep.py, sweep.json)

def _cell_label(cell: Mapping, skip: Sequence[str] = ()) -> str:
    return ", ".join(f"{a}={v}" for a, v in cell["labels"].items() if a not in skip) or "all"


def _model_names(cell: Mapping) -> dict[str, str]:
    """Filter name -> the paper's name of its dynamics model (the filter name for other models)."""
    models = PAPER_FORMATION_CQKF["models"]
    return {f: models.get(d.get("model"), f) for f, d in cell["filters"].items()}


def _display_names(cell: Mapping) -> dict[str, str]:
    """Filter name -> "name (paper model name)"."""
    return {f: f if m == f else f"{f} ({m})" for f, m in _model_names(cell).items()}


def _scored_cells(sweep: Mapping) -> list[Mapping]:
    return [c for c in sweep["cells"] if c.get("score")]


def _mae_cell(cell: Mapping, name: str, key: str, factor: float) -> str:
    block = cell["score"]["filters"][name]
    text = fmt_mean_se(block.get("mae_runs", {}).get(key) or [block["mae"][key]], factor)
    paper = (cell.get("paper") or {}).get("mae", {}).get(cell["filters"][name].get("model"), {}).get(key)
    return text if paper is None else f"{text} ({fmt(paper)})"


def sweep_paper_tables(sweep: Mapping) -> list[Table]:
    """Paper 004 Table 1-2 layout: per group of the non-column axes, components x (column level, filter)."""
    col = sweep.get("columns")
    if not col:
        return []
    groups: dict[str, list[Mapping]] = {}
    for cell in _scored_cells(sweep):
        groups.setdefault(_cell_label(cell, [col]), []).append(cell)
    tables = []
    for group, cells in groups.items():
        header = ["state"] + [f"{col}={c['labels'][col]}: {_display_names(c)[f]}" for c in cells
                              for f in c["score"]["filters"]]
        rows = [[f"{symbol} [{unit}]"] + [_mae_cell(c, f, key, factor) for c in cells for f in c["score"]["filters"]]
                for key, symbol, unit, factor in FORMATION_COMPONENTS]
        tables_ = sorted({c["paper"]["table"] for c in cells if c.get("paper")})
        ref = f" — paper Table {', '.join(map(str, tables_))} in parentheses" if tables_ else ""
        tables.append(Table(f"{group}: mean absolute error, bench mean ± standard error over runs{ref}", header, rows))
    return tables


def sweep_cells_table(sweep: Mapping) -> Table:
    """Every cell and filter: mean absolute error per component (mean ± SE over runs; paper in parentheses)."""
    rows = [[_cell_label(c), _display_names(c)[f], str(c["score"]["filters"][f]["runs"])]
            + [_mae_cell(c, f, key, factor) for key, _, _, factor in FORMATION_COMPONENTS]
            for c in _scored_cells(sweep) for f in c["score"]["filters"]]
    return Table("All cells: mean absolute error (mean ± standard error over runs; paper in parentheses)",
                 ["cell", "filter", "runs"] + [f"{s} [{u}]" for _, s, u, _ in FORMATION_COMPONENTS], rows)


def sweep_ordering_table(sweep: Mapping) -> Table:
    """Per cell and component: the bench's model ordering ("<" significant in a paired t-test over the same
    seeds at 5 %, "≈" not) and, where the paper has the case, the paper's ordering."""
    rows = []
    for c in _scored_cells(sweep):
        names = _model_names(c)
        models = {f: d.get("model") for f, d in c["filters"].items()}
        row = [_cell_label(c)]
        for key, _, _, _ in FORMATION_COMPONENTS:
            runs = {f: b.get("mae_runs", {}).get(key) or [b["mae"][key]] for f, b in c["score"]["filters"].items()}
            text = paired_ordering(runs, names)
            if c.get("paper"):
                text += f" (paper {_paper_ordering(c['paper'], models, key, names)})"
            row.append(text)
        rows.append(row)
    return Table("Model ordering by mean absolute error: '<' significant (paired t-test over the same seeds, 5 %), "
                 "'≈' not; the paper's ordering in parentheses",
                 ["cell"] + [s for _, s, _, _ in FORMATION_COMPONENTS], rows)


def sweep_consistency_table(sweep: Mapping) -> Table:
    rows = [(_cell_label(c), f, c["score"]["filters"][f], c["filters"][f].get("sigma_accel"))
            for c in _scored_cells(sweep) for f in c["score"]["filters"]]
    return formation_consistency_table("Consistency: time-averaged NEES of the run-averaged NEES (position and "
                                       "velocity) against its 95 % chi-square band, and the paper's ±3σ check", rows)


def _values_axis(ax, x: np.ndarray) -> None:
    """Logarithmic x axis over a wide range of swept values, ticks at the values themselves."""
    if x.max() >= 8.0 * x.min() > 0:
        ax.set_xscale("log")
    ax.set_xticks(x, [f"{v:g}" for v in x], fontsize=7)
    ax.xaxis.set_minor_formatter(NullFormatter())


def _draw_mae_vs(cells: Sequence[Mapping], axis: str, title: str) -> Callable[[Figure], None]:
    """MAE (mean ± SE over runs) against a numeric axis, one subplot per component, one line per filter."""
    def draw(fig: Figure) -> None:
        axs = fig.subplots(2, 3, sharex=True)
        x = np.array([c["values"][axis] for c in cells], dtype=float)
        for (key, symbol, unit, factor), ax in zip(FORMATION_COMPONENTS, axs.ravel()):
            for name in cells[0]["score"]["filters"]:
                stats = [mean_se(factor * np.asarray(c["score"]["filters"][name].get("mae_runs", {}).get(key)
                                                     or [c["score"]["filters"][name]["mae"][key]])) for c in cells]
                m, se = np.array(stats).T
                ax.errorbar(x, m, yerr=np.nan_to_num(se), marker="o", ms=3, capsize=2, lw=1.0,
                            label=_display_names(cells[0])[name])
            ax.set_yscale("log")
            _values_axis(ax, x)
            ax.set_title(f"{symbol} [{unit}]", fontsize=9)
            ax.grid(True, which="both", alpha=0.3)
        for ax in axs[1]:
            ax.set_xlabel(axis)
        axs[0, 0].legend(fontsize=7)
        fig.suptitle(title, fontsize=10)
    return draw


def _draw_nees_vs(cells: Sequence[Mapping], axis: str, title: str) -> Callable[[Figure], None]:
    """Time-averaged NEES against a numeric axis, one line per filter, with the 95 % band of the runs."""
    def draw(fig: Figure) -> None:
        ax = fig.subplots()
        x = np.array([c["values"][axis] for c in cells], dtype=float)
        for name in cells[0]["score"]["filters"]:
            ax.plot(x, [c["score"]["filters"][name]["nees_mean"] for c in cells], marker="o", ms=3, lw=1.0,
                    label=_display_names(cells[0])[name])
        lo, hi = np.array([c["score"]["filters"][name]["nees_bounds"] for c in cells], dtype=float).T
        ax.fill_between(x, lo, hi, color="0.85", label="95 % band")
        ax.set(xlabel=axis, ylabel="time-averaged NEES (6 dof)", title=title)
        ax.set_yscale("log")
        _values_axis(ax, x)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    return draw


def _numeric_groups(sweep: Mapping) -> tuple[str | None, dict[str, list[Mapping]]]:
    """The first numeric axis and the scored cells grouped by the labels of the other axes."""
    numeric = [a for a, spec in sweep["axes"].items() if spec.get("numeric")]
    groups: dict[str, list[Mapping]] = {}
    if numeric:
        for c in _scored_cells(sweep):
            groups.setdefault(_cell_label(c, [numeric[0]]), []).append(c)
    return (numeric[0] if numeric else None), groups


def sweep_consistent_values_table(sweep: Mapping) -> list[Table]:
    """Per group and filter: the smallest value of the numeric axis whose time-averaged NEES is inside the
    runs' 95 % band (the process-noise tuning rule of the ``sigma`` grid)."""
    axis, groups = _numeric_groups(sweep)
    if axis is None:
        return []
    rows = []
    for group, cells in groups.items():
        for name in cells[0]["score"]["filters"]:
            inside = [c["values"][axis] for c in cells
                      if c["score"]["filters"][name]["nees_bounds"][0] <= c["score"]["filters"][name]["nees_mean"]
                      <= c["score"]["filters"][name]["nees_bounds"][1]]
            rows.append([group, _display_names(cells[0])[name], fmt(min(inside)) if inside else "none"])
    return [Table(f"Smallest {axis} with the time-averaged NEES inside the 95 % band",
                  ["cells", "filter", axis], rows)]


def sweep_plots(sweep: Mapping, series: Mapping[str, Mapping]) -> list[Plot]:
    """MAE against the first numeric axis (per level of the other axes), and for every cell the paper has,
    the error RMSE over runs against the 3σ bounds in time (paper 004 Figs. 1-6)."""
    plots = []
    axis, groups = _numeric_groups(sweep)
    for i, (group, members) in enumerate(groups.items()):
        plots.append(Plot(f"mae_vs_{axis}_{i}.png", f"Mean absolute error vs {axis} ({group}); "
                          "error bars: ± standard error over runs", _draw_mae_vs(members, axis, group), (11.0, 6.0)))
        plots.append(Plot(f"nees_vs_{axis}_{i}.png", f"Time-averaged NEES vs {axis} ({group})",
                          _draw_nees_vs(members, axis, group), (7.0, 4.5)))
    for c in _scored_cells(sweep):
        if c.get("paper") and series.get(c["id"]):
            plots.append(Plot(f"errors_{c['id']}.png", f"Error RMSE over runs vs the filters' 3σ: {_cell_label(c)}",
                              _draw_formation_errors(series[c["id"]], _cell_label(c)), (11.0, 6.0)))
    return plots


def write_sweep_report(out_dir: Path | str, sweep: Mapping, series: Mapping[str, Mapping],
                       model_error_markdown: str = "") -> Path:
    """Write ``table.md`` and its PNGs for a sweep (``sweep.json`` content); returns the Markdown path."""
    cells = sweep["cells"]
    reused = f" for the runs not reused from an earlier invocation ({sweep['runs_reused']} reused)" \
        if sweep.get("runs_reused") else ""
    text = (f"{sweep.get('description', '')}\n\nGrid '{sweep['grid']}' of {sweep['scenario']}: {len(cells)} cells "
            f"x {sweep['runs_per_cell']} runs (seeds {sweep['seed0']}..{sweep['seed0'] + sweep['runs_per_cell'] - 1}, "
            f"the same in every cell), wall time {sweep['wall_s']:.0f} s with {sweep['jobs']} parallel jobs"
            f"{reused}.\n\nCommand: `{sweep['command']}`")
    if any(c.get("paper") for c in cells):
        text += (f"\n\nPaper: {PAPER_FORMATION_CQKF['source']}.\n\n"
                 + "\n".join(f"- {n}" for n in PAPER_FORMATION_CQKF["notes"]))
    if sweep.get("crosstalk_reruns"):
        text += ("\n\nRuns repeated because another graph published on their ROS domain:\n\n"
                 + "\n".join(f"- {r}" for r in sweep["crosstalk_reruns"]))
    if sweep.get("failures"):
        text += "\n\nFailures:\n\n" + "\n".join(f"- {f}" for f in sweep["failures"])
    tables = sweep_paper_tables(sweep) + [sweep_ordering_table(sweep), sweep_cells_table(sweep),
                                          sweep_consistency_table(sweep)] + sweep_consistent_values_table(sweep)
    sections = [Section(f"{sweep['scenario']} — sweep '{sweep['grid']}'", text, tables, sweep_plots(sweep, series))]
    if model_error_markdown:
        sections.append(Section(
            "Model error against the nonlinear truth (scripts/model_error.py)",
            "Unmodelled acceleration (truth relative acceleration from finite differences minus the model's A x) "
            "per LVLH axis (x radial, y along-track, z cross-track) and the RMS one-step position prediction "
            "error over 1 s and 10 s; CW+bias with its best constant bias removed.\n\n" + model_error_markdown))
    return render(Path(out_dir), sections, f"Sweep {sweep['scenario']} / {sweep['grid']}", filename="table.md")
