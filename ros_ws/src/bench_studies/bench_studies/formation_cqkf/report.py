"""The formation_cqkf report: paper 004's Tables 1-2 next to the bench (mean ± Monte Carlo standard error),
consistency, error-vs-3-sigma figures, and the sweep report (paper-style tables per case, model ordering with
paired significance, numeric-axis plots).

The paper's numbers come from paper.yaml beside this file.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import NullFormatter
from scipy.special import stdtrit  # Student t quantile: t.ppf(q, df) = stdtrit(df, q)

from bench_engine.timegrid import build_time
from bench_eval.report import Plot, Section, Table, bounds_table, draw_errors_vs_sigma, fmt, paper_note, render
from bench_eval.study import load_paper
from orbit_sim.truth import Formation, read_truth
from radar_sensor.sensor_types import read_sensors

PAPER, CLAIMS = load_paper(Path(__file__).with_name("paper.yaml"))


FORMATION_COMPONENTS = (
    ("x", "δx", "m", 1.0),
    ("y", "δy", "m", 1.0),
    ("z", "δz", "m", 1.0),
    ("vx", "δvx", "mm/s", 1e3),
    ("vy", "δvy", "mm/s", 1e3),
    ("vz", "δvz", "mm/s", 1e3),
)
"""Formation state components: score key, paper symbol, paper unit, factor from SI to that unit."""


def paper004_case(cfg: Mapping) -> dict | None:
    """The paper 004 table case a resolved ``formation_cqkf`` configuration reproduces, or None.

    A case needs the chief's e and the relative orbit size of the table, nonlinear (range/angles)
    measurements every 1 s and a 1 s step.
    """
    truth = read_truth(cfg).options
    radio = [s for s in read_sensors(cfg).values() if s.type == "isl_radio"]
    if (
        not isinstance(truth, Formation)
        or truth.deputy.pco is None
        or len(radio) != 1
        or radio[0].interval != 1.0
        or build_time(cfg).dt != 1.0
    ):
        return None
    e, size = truth.chief.e, truth.deputy.pco.size
    return next((c for c in PAPER["cases"] if np.isclose(c["e"], e, atol=1e-9) and np.isclose(c["rho_m"], size)), None)


def mean_se(values: Sequence[float]) -> tuple[float, float]:
    """Mean and standard error (s / sqrt(N); NaN for one value) of per-run values."""
    v = np.asarray(values, dtype=float)
    return float(np.mean(v)), float(np.std(v, ddof=1) / np.sqrt(len(v))) if len(v) > 1 else float("nan")


def fmt_mean_se(values: Sequence[float], factor: float = 1.0) -> str:
    """ "mean ± SE" of per-run values in a display unit (``factor`` from SI)."""
    m, se = mean_se(np.asarray(values, dtype=float) * factor)
    return f"{m:.3g}" if not np.isfinite(se) else f"{m:.3g} ± {se:.2g}"


def paired_ordering(
    mae_runs: Mapping[str, Sequence[float]], names: Mapping[str, str] | None = None, alpha: float = 0.05
) -> str:
    """Filters sorted by mean error, "<" where the paired difference over the same runs is significant
    (two-sided t-test at ``alpha``), "≈" where it is not (always "≈" with a single run)."""
    order = sorted(mae_runs, key=lambda k: float(np.mean(mae_runs[k])))
    label = (lambda k: names.get(k, k)) if names else str
    text = label(order[0])
    for a, b in zip(order, order[1:]):
        d = np.asarray(mae_runs[b], dtype=float) - np.asarray(mae_runs[a], dtype=float)
        n = len(d)
        se = np.std(d, ddof=1) / np.sqrt(n) if n > 1 else 0.0
        significant = n > 1 and se > 0 and np.mean(d) / se > stdtrit(n - 1, 1.0 - 0.5 * alpha)
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
        rows.append(
            [
                case,
                name,
                fmt(sigma) if not isinstance(sigma, str) else sigma,
                str(b.get("runs")),
                fmt(b.get("nees_mean")),
                fmt(b.get("nees_bounds")),
                fmt(b.get("nees_fraction_inside")),
                f"{min(inside):.0%}–{max(inside):.0%}" if inside else "—",
            ]
        )
    return Table(
        title,
        [
            "case",
            "filter",
            "sigma_accel [m/s^1.5]",
            "runs",
            "mean NEES (6 dof)",
            "95 % band",
            "steps inside band",
            "errors within ±3σ (per component)",
        ],
        rows,
    )


def _filter_models(scored: Mapping) -> dict[str, str]:
    """Bench filter name -> paper 004 dynamics model key, by name (ss, cw, cwb as in the scenario)."""
    by_name = {"ss": "ss", "cw": "cw", "cwb": "cw_bias"}
    return {n: by_name[n] for n in scored if n in by_name}


def formation_cqkf_sections(
    scenario: str, scored: Mapping, series: Mapping | None, paper: Mapping | None
) -> list[Section]:
    """Sections for one ``formation_cqkf`` run or Monte Carlo (its default case e = 0, rho = 1 km, 1 s)."""
    case = next((c for c in (paper or {}).get("cases", []) if c["e"] == 0.0 and c["rho_m"] == 1000.0), None)
    text = (
        "Bench mean absolute error (± standard error over runs) next to paper 004 Table 1, rho = 1 km, "
        "which is the scenario's default case: the paper column does not apply to runs with variants "
        "(scripts/sweep.py compares every case of the paper's grid)."
    )
    if paper:
        text += "\n\n" + paper_note(paper)
    tables = [
        formation_mae_table("Mean absolute error (bench vs paper Table 1, 1 km)", scored, case, _filter_models(scored)),
        formation_consistency_table("Consistency", [("scenario as run", n, b, "—") for n, b in scored.items()]),
    ]
    tables += [t for t in [bounds_table(scored, BOUND_GROUPS)] if t]
    plots = (
        [
            Plot(
                f"{scenario}_errors.png",
                "Error RMSE over runs against the filters' 3σ (paper 004 Figs. 1-6)",
                draw_errors_vs_sigma(series, scenario, FORMATION_COMPONENTS),
                (11.0, 6.0),
            )
        ]
        if series
        else []
    )
    return [Section(scenario, text, tables, plots)]


def _cell_label(cell: Mapping, skip: Sequence[str] = ()) -> str:
    return ", ".join(f"{a}={v}" for a, v in cell["labels"].items() if a not in skip) or "all"


def _model_names(cell: Mapping) -> dict[str, str]:
    """Filter name -> the paper's name of its dynamics model (the filter name for other models)."""
    models = PAPER["models"]
    return {f: models.get(d.get("model"), f) for f, d in cell["estimators"].items()}


def _display_names(cell: Mapping) -> dict[str, str]:
    """Filter name -> "name (paper model name)"."""
    return {f: f if m == f else f"{f} ({m})" for f, m in _model_names(cell).items()}


def _scored_cells(sweep: Mapping) -> list[Mapping]:
    return [c for c in sweep["cells"] if c.get("score")]


def _mae_cell(cell: Mapping, name: str, key: str, factor: float) -> str:
    block = cell["score"]["estimators"][name]
    text = fmt_mean_se(block.get("mae_runs", {}).get(key) or [block["mae"][key]], factor)
    paper = (cell.get("paper") or {}).get("mae", {}).get(cell["estimators"][name].get("model"), {}).get(key)
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
        header = ["state"] + [
            f"{col}={c['labels'][col]}: {_display_names(c).get(f, f)}" for c in cells for f in c["score"]["estimators"]
        ]
        rows = [
            [f"{symbol} [{unit}]"] + [_mae_cell(c, f, key, factor) for c in cells for f in c["score"]["estimators"]]
            for key, symbol, unit, factor in FORMATION_COMPONENTS
        ]
        tables_ = sorted({c["paper"]["table"] for c in cells if c.get("paper")})
        ref = f" — paper Table {', '.join(map(str, tables_))} in parentheses" if tables_ else ""
        tables.append(Table(f"{group}: mean absolute error, bench mean ± standard error over runs{ref}", header, rows))
    return tables


def sweep_cells_table(sweep: Mapping) -> Table:
    """Every cell and filter: mean absolute error per component (mean ± SE over runs; paper in parentheses)."""
    rows = [
        [_cell_label(c), _display_names(c).get(f, f), str(c["score"]["estimators"][f]["runs"])]
        + [_mae_cell(c, f, key, factor) for key, _, _, factor in FORMATION_COMPONENTS]
        for c in _scored_cells(sweep)
        for f in c["score"]["estimators"]
    ]
    return Table(
        "All cells: mean absolute error (mean ± standard error over runs; paper in parentheses)",
        ["cell", "filter", "runs"] + [f"{s} [{u}]" for _, s, u, _ in FORMATION_COMPONENTS],
        rows,
    )


def sweep_ordering_table(sweep: Mapping) -> Table:
    """Per cell and component: the bench's model ordering ("<" significant in a paired t-test over the same
    seeds at 5 %, "≈" not) and, where the paper has the case, the paper's ordering."""
    rows = []
    for c in _scored_cells(sweep):
        names = _model_names(c)
        models = {f: d.get("model") for f, d in c["estimators"].items()}
        row = [_cell_label(c)]
        for key, _, _, _ in FORMATION_COMPONENTS:
            runs = {f: b.get("mae_runs", {}).get(key) or [b["mae"][key]] for f, b in c["score"]["estimators"].items()}
            text = paired_ordering(runs, names)
            if c.get("paper"):
                text += f" (paper {_paper_ordering(c['paper'], models, key, names)})"
            row.append(text)
        rows.append(row)
    return Table(
        "Model ordering by mean absolute error: '<' significant (paired t-test over the same seeds, 5 %), "
        "'≈' not; the paper's ordering in parentheses",
        ["cell"] + [s for _, s, _, _ in FORMATION_COMPONENTS],
        rows,
    )


BOUND_GROUPS = (("position", "m", 1.0), ("velocity", "mm/s", 1e3))
"""The groups of the bound tables (bench_eval.report.bounds_table): key, display unit, factor from SI."""


def sweep_bounds_table(sweep: Mapping) -> Table | None:
    """Every cell and filter: position and velocity RMSE over the orbit next to the posterior CRB with the
    truth's dynamics and the cell's measurements (scenario scoring.bounds), and the efficiency (bench_eval.bounds)."""
    rows = []
    for c in _scored_cells(sweep):
        for f, block in c["score"]["estimators"].items():
            for bound, b in (block.get("bounds") or {}).items():
                cells = []
                for key, _, factor in BOUND_GROUPS:
                    g = b.get(key) or {}
                    cells += [
                        fmt(None if g.get("rmse") is None else factor * g["rmse"]),
                        fmt(None if g.get("sqrt_bound") is None else factor * g["sqrt_bound"]),
                        fmt(g.get("efficiency")),
                    ]
                rows.append([_cell_label(c), _display_names(c).get(f, f), bound] + cells)
    if not rows:
        return None
    return Table(
        "Distance to the bound per cell: RMSE over runs and the orbit (RMS over time) next to √bound, "
        "efficiency (mean over the orbit of RMSE² / bound)^-½",
        [
            "cell",
            "filter",
            "bound",
            "position RMSE [m]",
            "√bound [m]",
            "efficiency",
            "velocity RMSE [mm/s]",
            "√bound [mm/s]",
            "efficiency",
        ],
        rows,
    )


def sweep_consistency_table(sweep: Mapping) -> Table:
    rows = [
        (_cell_label(c), f, c["score"]["estimators"][f], c["estimators"][f].get("sigma_accel"))
        for c in _scored_cells(sweep)
        for f in c["score"]["estimators"]
    ]
    return formation_consistency_table(
        "Consistency: time-averaged NEES of the run-averaged NEES (position and "
        "velocity) against its 95 % chi-square band, and the paper's ±3σ check",
        rows,
    )


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
            for name in cells[0]["score"]["estimators"]:
                stats = [
                    mean_se(
                        factor
                        * np.asarray(
                            c["score"]["estimators"][name].get("mae_runs", {}).get(key)
                            or [c["score"]["estimators"][name]["mae"][key]]
                        )
                    )
                    for c in cells
                ]
                m, se = np.array(stats).T
                ax.errorbar(
                    x,
                    m,
                    yerr=np.nan_to_num(se),
                    marker="o",
                    ms=3,
                    capsize=2,
                    lw=1.0,
                    label=_display_names(cells[0])[name],
                )
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
        for name in cells[0]["score"]["estimators"]:
            ax.plot(
                x,
                [c["score"]["estimators"][name]["nees_mean"] for c in cells],
                marker="o",
                ms=3,
                lw=1.0,
                label=_display_names(cells[0])[name],
            )
        lo, hi = np.array([c["score"]["estimators"][name]["nees_bounds"] for c in cells], dtype=float).T
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
        for name in cells[0]["score"]["estimators"]:
            inside = [
                c["values"][axis]
                for c in cells
                if c["score"]["estimators"][name]["nees_bounds"][0]
                <= c["score"]["estimators"][name]["nees_mean"]
                <= c["score"]["estimators"][name]["nees_bounds"][1]
            ]
            rows.append([group, _display_names(cells[0])[name], fmt(min(inside)) if inside else "none"])
    return [Table(f"Smallest {axis} with the time-averaged NEES inside the 95 % band", ["cells", "filter", axis], rows)]


def sweep_plots(sweep: Mapping, series: Mapping[str, Mapping]) -> list[Plot]:
    """MAE against the first numeric axis (per level of the other axes), and for every cell the paper has,
    the error RMSE over runs against the 3σ bounds in time (paper 004 Figs. 1-6)."""
    plots = []
    axis, groups = _numeric_groups(sweep)
    for i, (group, members) in enumerate(groups.items()):
        plots.append(
            Plot(
                f"mae_vs_{axis}_{i}.png",
                f"Mean absolute error vs {axis} ({group}); error bars: ± standard error over runs",
                _draw_mae_vs(members, axis, group),
                (11.0, 6.0),
            )
        )
        plots.append(
            Plot(
                f"nees_vs_{axis}_{i}.png",
                f"Time-averaged NEES vs {axis} ({group})",
                _draw_nees_vs(members, axis, group),
                (7.0, 4.5),
            )
        )
    for c in _scored_cells(sweep):
        if c.get("paper") and series.get(c["id"]):
            plots.append(
                Plot(
                    f"errors_{c['id']}.png",
                    f"Error RMSE over runs vs the filters' 3σ: {_cell_label(c)}",
                    draw_errors_vs_sigma(series[c["id"]], _cell_label(c), FORMATION_COMPONENTS),
                    (11.0, 6.0),
                )
            )
    return plots


def write_sweep_report(
    out_dir: Path | str, sweep: Mapping, series: Mapping[str, Mapping], model_error_markdown: str = ""
) -> Path:
    """Write ``table.md`` and its PNGs for a sweep (``sweep.json`` content); returns the Markdown path."""
    cells = sweep["cells"]
    reused = (
        f" for the runs not reused from an earlier invocation ({sweep['runs_reused']} reused)"
        if sweep.get("runs_reused")
        else ""
    )
    text = (
        f"{sweep.get('description', '')}\n\nGrid '{sweep['grid']}' of {sweep['scenario']}: {len(cells)} cells "
        f"x {sweep['runs_per_cell']} runs (seeds {sweep['seed0']}..{sweep['seed0'] + sweep['runs_per_cell'] - 1}, "
        f"the same in every cell), wall time {sweep['wall_s']:.0f} s with {sweep['jobs']} parallel jobs"
        f"{reused}.\n\nCommand: `{sweep['command']}`"
    )
    if any(c.get("paper") for c in cells):
        text += f"\n\nPaper: {PAPER['source']}.\n\n" + "\n".join(f"- {n}" for n in PAPER["notes"])
    if sweep.get("crosstalk_reruns"):
        text += "\n\nRuns repeated because another graph published on their ROS domain:\n\n" + "\n".join(
            f"- {r}" for r in sweep["crosstalk_reruns"]
        )
    if sweep.get("failures"):
        text += "\n\nFailures:\n\n" + "\n".join(f"- {f}" for f in sweep["failures"])
    tables = (
        sweep_paper_tables(sweep)
        + [sweep_ordering_table(sweep), sweep_cells_table(sweep), sweep_consistency_table(sweep)]
        + sweep_consistent_values_table(sweep)
    )
    tables += [t for t in [sweep_bounds_table(sweep)] if t]
    sections = [Section(f"{sweep['scenario']} — sweep '{sweep['grid']}'", text, tables, sweep_plots(sweep, series))]
    if model_error_markdown:
        sections.append(
            Section(
                "Model error against the nonlinear truth (scripts/model_error.py)",
                "Unmodelled acceleration (truth relative acceleration from finite differences minus the model's A x) "
                "per LVLH axis (x radial, y along-track, z cross-track) and the RMS one-step position prediction "
                "error over 1 s and 10 s; CW+bias with its best constant bias removed.\n\n" + model_error_markdown,
            )
        )
    return render(Path(out_dir), sections, f"Sweep {sweep['scenario']} / {sweep['grid']}", filename="table.md")
