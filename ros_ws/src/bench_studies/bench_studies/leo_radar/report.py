"""The leo_radar report section: paper 000's Tables 2 and 3 next to the bench, NEES, and three figures."""

from __future__ import annotations

from collections.abc import Callable, Mapping

from matplotlib.figure import Figure
from matplotlib.ticker import LogFormatter

from bench_eval.report import Plot, Section, Table, bounds_table, difference, draw_bounds, fmt, paper_note


def _paper_filter(paper: Mapping | None, name: str) -> Mapping:
    """The paper's block for a bench filter name, matched case-insensitively (empty if absent)."""
    filters = (paper or {}).get("filters", {})
    return next((v for k, v in filters.items() if k.lower() == name.lower()), {})


LEO_QUANTITIES = (("rmse_peak_m", "peak [m]"), ("convergence_time_s", "convergence time [s]"), ("band_m", "band [m]"))


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
        rows.append(
            [
                "position RMSE",
                "converged [m]",
                name,
                fmt(block.get(key)),
                fmt(ref.get(key)),
                difference(block.get(key), ref.get(key)),
            ]
        )
    return Table(
        "Table 2 — position error (bench vs paper)",
        ["quantity", "statistic", "filter", "bench", "paper", "difference"],
        rows,
    )


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
    return Table(
        "Table 3 — RMSE in radar coordinates (bench vs paper)",
        ["component", "source", "bench", "paper", "difference"],
        rows,
    )


def radar_bounds_table(scored: Mapping) -> Table | None:
    """RMSE in radar coordinates next to each bound mapped there, from the bound's ``from_s`` on
    (leo_radar/radar_bound.py), and the ratio √bound / RMSE; None without bounds."""
    rows = []
    for name, block in scored.items():
        for bound, values in ((block.get("radar") or {}).get("bounds") or {}).items():
            rows += [
                [key, name, bound, fmt(v["rmse"]), fmt(v["sqrt_bound"]), fmt(v["ratio"])] for key, v in values.items()
            ]
    if not rows:
        return None
    return Table(
        "Distance to the bound in radar coordinates (the scans from the bound's from_s on, pooled over runs)",
        ["component", "filter", "bound", "RMSE", "√bound", "√bound / RMSE"],
        rows,
    )


def nees_table(scored: Mapping) -> Table:
    """Filter consistency: time-averaged NEES against its chi-square bounds (not reported by the papers)."""
    rows = [
        [
            name,
            str(b.get("runs")),
            fmt(b.get("nees_mean")),
            str(b.get("nees_dof")),
            fmt(b.get("nees_bounds")),
            fmt(b.get("nees_fraction_inside")),
        ]
        for name, b in scored.items()
        if "nees_mean" in b
    ]
    return Table(
        "NEES consistency (95 % two-sided chi-square bounds of the run-averaged NEES)",
        ["filter", "runs", "mean NEES", "dof", "bounds", "fraction of steps inside"],
        rows,
    )


def _draw_rmse(series: Mapping, scored: Mapping, paper: Mapping | None) -> Callable[[Figure], None]:
    def draw(fig: Figure) -> None:
        ax = fig.subplots()
        for name, s in series.items():
            (line,) = ax.semilogy(s["t"], s["rmse"], lw=1.0, label=name)
            tc = scored.get(name, {}).get("convergence_time_s")
            if tc is not None:
                ax.axvline(
                    s["t"][0] + tc, color=line.get_color(), ls=":", lw=1.0, label=f"{name} converged ({tc:.1f} s)"
                )
            level = _paper_filter(paper, name).get("rmse_converged_m")
            if level is not None:
                ax.axhline(
                    level, color=line.get_color(), ls="--", lw=0.8, label=f"paper {name} converged ({level:g} m)"
                )
        draw_bounds(ax, series, "position")
        ax.set(
            xlabel="time since first estimate [s]",
            ylabel="position RMSE [m]",
            title="Position RMSE over Monte Carlo runs (paper 000 eq. 35)",
        )
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
            draw_bounds(ax, series, lab)
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
        text = paper_note(paper)
    tables = [leo_table2(scored, paper), nees_table(scored)]
    if any("radar" in b for b in scored.values()):
        tables.insert(1, leo_table3(scored, paper))
    tables += [t for t in (bounds_table(scored), radar_bounds_table(scored)) if t]
    plots = []
    if series:
        plots = [
            Plot(f"{scenario}_rmse.png", "Position RMSE vs time (log scale)", _draw_rmse(series, scored, paper)),
            Plot(f"{scenario}_axes.png", "Per-axis error vs time", _draw_axes(series), (9.0, 7.0)),
            Plot(
                f"{scenario}_nees.png",
                "NEES vs time with the chi-square band",
                _draw_nees(series),
                (9.0, 2.5 + 2.5 * len(series)),
            ),
        ]
    return [Section(scenario, text, tables, plots)]
