"""Markdown + PNG report: the paper claims' verdicts first, then a section per study (tables of the bench next
to the paper, figures).

Figures are drawn on ``matplotlib.figure.Figure`` objects (Agg canvas, no pyplot state), so the report can be
written from any thread or a headless CI run. A study's sections come from its registered Study
(bench_eval.study); a scenario without one gets a generic table of its scalar scores. Nothing here knows a
study by name.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from bench_eval.claims import evaluate
from bench_eval.study import study


@dataclass
class Table:
    """A Markdown table: title, header and rows of already formatted cells."""

    title: str
    header: list[str]
    rows: list[list[str]]

    def markdown(self) -> str:
        lines = [f"**{self.title}**", "", "| " + " | ".join(self.header) + " |", "|" + "---|" * len(self.header)]
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


def paper_note(paper: Mapping) -> str:
    """A study's paper in Markdown: its ``source`` and ``notes`` (paper.yaml)."""
    return f"Paper: {paper.get('source', '')}.\n\n" + "\n".join(f"- {n}" for n in paper.get("notes", []))


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


def thin(t: np.ndarray, max_points: int = 2000) -> slice:
    """A stride that keeps at most about ``max_points`` points of a long time series for plotting."""
    return slice(None, None, max(1, len(t) // max_points))


BOUND_STYLE = {"color": "k", "ls": (0, (6, 2)), "lw": 1.3}
"""How every figure draws a bound's square root (bench_eval.bounds): a black dashed curve."""


def bound_curves(series: Mapping, key: str) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(bound name, t, √bound) of component or group ``key`` from the scorer's ``bounds`` series of the
    estimators (bench_eval.bounds), one curve per bound: the first estimator's that has it (the bound does not
    depend on the estimator; the time axis is the series')."""
    curves = {}
    for s in series.values():
        for name, b in (s.get("bounds") or {}).items():
            values = b.get(key, (b.get("axes") or {}).get(key))
            if values is not None and name not in curves:
                curves[name] = (name, np.asarray(b["t"]), np.asarray(values))
    return list(curves.values())


def draw_bounds(ax, series: Mapping, key: str, factor: float = 1.0) -> None:
    """Add each bound's √bound of ``key`` to a log-scale axis (BOUND_STYLE), labelled "√NAME"."""
    for name, t, values in bound_curves(series, key):
        k = thin(t)
        ax.semilogy(t[k], factor * values[k], label=f"√{name.upper()}", **BOUND_STYLE)


def bounds_table(
    scored: Mapping, groups: Sequence[tuple[str, str, float]] = (("position", "m", 1.0), ("velocity", "m/s", 1.0))
) -> Table | None:
    """Every estimator's RMSE next to each bound's square root and its efficiency (bench_eval.bounds: 1 = reaches
    the bound), per group (key, display unit, factor from SI): RMS over the summarised steps and at the last step
    (bench_eval.bounds); None when no estimator was scored against a bound."""
    rows = []
    for est, block in scored.items():
        for bound, b in (block.get("bounds") or {}).items():
            for key, unit, factor in groups:
                g = b.get(key, (b.get("axes") or {}).get(key))
                if not g or g.get("rmse") is None:
                    continue
                rows.append(
                    [
                        est,
                        bound,
                        f"{key} [{unit}]",
                        fmt(factor * g["rmse"]),
                        fmt(factor * g["sqrt_bound"]),
                        fmt(g["efficiency"]),
                        fmt(factor * g["final_rmse"]),
                        fmt(factor * g["final_sqrt_bound"]),
                    ]
                )
    if not rows:
        return None
    return Table(
        "Distance to the bound: RMSE over runs next to √bound (RMS over the summarised steps), efficiency "
        "(mean over those steps of RMSE² / bound)^-½ (1 = the best the data allow), both at the last step",
        ["estimator", "bound", "quantity", "RMSE", "√bound", "efficiency", "last RMSE", "last √bound"],
        rows,
    )


def draw_errors_vs_sigma(
    series: Mapping, title: str, components: Sequence[tuple[str, str, str, float]]
) -> Callable[[Figure], None]:
    """A figure of the ``errors`` family's series (bench_eval.metric_families.error_series): per component
    (score key, symbol, display unit, factor from SI to it), the error RMSE over runs (solid) and the filter's
    mean 3 sigma (dashed), one colour per filter, and each bound's √bound (black dashed: :func:`draw_bounds`), on
    log axes, in a grid of 3 columns."""

    def draw(fig: Figure) -> None:
        rows = max(1, -(-len(components) // 3))
        axs = np.atleast_2d(fig.subplots(rows, 3, sharex=True, squeeze=False))
        for (key, symbol, unit, factor), ax in zip(components, axs.ravel()):
            for name, s in series.items():
                if key not in s["rmse"]:
                    continue
                k = thin(s["t"])
                (line,) = ax.semilogy(s["t"][k], factor * np.asarray(s["rmse"][key])[k], lw=0.8, label=f"{name} RMSE")
                ax.semilogy(
                    s["t"][k],
                    3.0 * factor * np.asarray(s["sigma"][key])[k],
                    lw=0.8,
                    ls="--",
                    color=line.get_color(),
                    label=f"{name} 3σ",
                )
            draw_bounds(ax, series, key, factor)
            ax.set_title(f"{symbol} [{unit}]", fontsize=9)
            ax.grid(True, which="both", alpha=0.3)
        for ax in axs[-1]:
            ax.set_xlabel("time [s]")
        axs[0, 0].legend(fontsize=7)
        fig.suptitle(title, fontsize=10)

    return draw


def save_plot(out_dir: Path, plot: Plot) -> Path:
    """Draw and write one plot as PNG; returns its path."""
    fig = Figure(figsize=plot.size, layout="constrained")
    FigureCanvasAgg(fig)
    plot.draw(fig)
    path = out_dir / plot.filename
    fig.savefig(path, dpi=110)
    return path


def render(
    out_dir: Path, sections: Sequence[Section], title: str = "Tracking bench report", filename: str = "report.md"
) -> Path:
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


def claims_section(rows: Sequence) -> Section:
    """The report's opening table: every paper claim, the bench's figure and the verdict (bench_eval.claims)."""
    table = Table(
        "Paper claims tested by the bench (bench figures: mean ± Monte Carlo standard error where the runs give one)",
        ["study", "claim", "paper", "bench", "verdict"],
        [[f"[{r.study}](#{r.section})", r.claim, r.paper, r.bench, f"**{r.verdict}**"] for r in rows],
    )
    return Section("Claims", "", [table])


def write_report(
    out_dir: Path | str,
    scored: Mapping,
    series: Mapping,
    paper_table: Mapping | None = None,
    extra_sections: Sequence[Section] = (),
) -> Path:
    """Write ``report.md`` and its PNGs into ``out_dir``; returns the Markdown path.

    ``scored``: {scenario: {filter: score block}}; ``series``: {scenario: {filter: time series}} (may lack
    scenarios); ``paper_table``: {scenario: paper numbers} replacing the studies' own (pass {} for no paper
    columns and no claims). ``extra_sections`` are appended after the scenario sections.
    """
    sections, claims = [], []
    for scenario, block in scored.items():
        found = study(scenario)
        paper = found.paper if found and paper_table is None else (paper_table or {}).get(scenario)
        if found and paper_table is None:
            claims += evaluate(scenario, block, found.claims, scenario)
        builder = found.sections if found and found.sections else generic_sections
        sections += builder(scenario, block, series.get(scenario), paper)
    opening = [claims_section(claims)] if claims else []
    return render(Path(out_dir), opening + sections + list(extra_sections))
