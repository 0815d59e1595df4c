"""Parameter sweeps: every cell of a grid of the scenario's ``sweeps`` section through the graph, N seeded runs
per cell (the one Monte Carlo runner, bench_engine.batch), scored per cell as its last run ends.

Grids are declared in the scenario's ``sweeps`` section; a grid is the product of its axes, in order:

    sweeps:
      tables:
        description: free text
        columns: rho                 # optional: axis whose levels are the paper-style table's columns
        set: {scoring.bounds: {}}    # optional: overrides of every cell (here: no bound is computed)
        axes:
          e: {"0": [], "0.005": [e0005]}                 # level label -> variants applied in axis order
          rho: {1km: [], 10km: [size10km]}
          measurement: {range_angles: [], linear: ["linear_{rho}"]}   # {axis} = that axis' level label
          interval: {1s: [], 10s: {set: {time.dt: 10.0, sensors.isl.interval: 10.0}}}
      interval:
        axes:
          interval_s: {values: [1, 2, 5, 10], set: [time.dt, sensors.isl.interval]}    # numeric axis
          noise: {values: [0.5, 1, 2], scale: [sensors.isl.sigma_range, sensors.isl.sigma_position]}

A level is a list of variants or a mapping {variants: [...], set: {key: value}}. A numeric axis sets each
value on every ``set`` key and multiplies every ``scale`` key by it (keys a cell lacks are skipped; a key no
cell has, or a cell with none of them, is an error). A cell applies its variants, then the grid's ``set``, its
levels' ``set`` and ``scale`` overrides, then the command line's --set. Every cell is resolved and validated
before the first run.
Run i of every cell uses seed SEED0 + i (the same noise realisations in every cell) and writes
OUT/CELL/run_NNN/bag. The study's hooks (bench_eval.study) give the paper's case of a cell, the sweep report
and extra rows (e.g. a model-error table); without them a generic table is written.
"""

from __future__ import annotations

import itertools
import json
import re
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench_engine.batch import RunResult, RunSpec, reusable_run, run_batch
from bench_engine.config import (
    ScenarioError,
    Section,
    apply_overrides,
    load_scenario,
    lookup,
    override_strings,
    select_variant,
)
from bench_engine.graph import resolve_estimators
from bench_engine.launcher import prepare_run
from bench_eval.metrics import json_ready
from bench_eval.report import Section as ReportSection
from bench_eval.report import generic_sections, render
from bench_eval.scoring import score_bags
from bench_eval.study import study
from tracker_filters.filter_settings import filter_config, filter_key

PLACEHOLDER = re.compile(r"\{([^{}]*)\}")


@dataclass
class Level:
    """One level of an axis: variants (may name other axes as {axis}), set and scale overrides."""

    variants: list[str] = field(default_factory=list)
    sets: dict[str, Any] = field(default_factory=dict)
    scales: dict[str, float] = field(default_factory=dict)
    value: float | None = None


@dataclass
class Axis:
    name: str
    levels: dict[str, Level]
    numeric: bool = False


@dataclass
class Cell:
    """One point of the grid, resolved: the variants and overrides its runs get, and the resulting config."""

    labels: dict[str, str]
    values: dict[str, float | None]
    variants: list[str]
    overrides: list[str]
    cfg: dict

    @property
    def id(self) -> str:
        return "__".join(f"{k}-{re.sub(r'[^A-Za-z0-9.+-]', '_', v)}" for k, v in self.labels.items())


@dataclass
class Grid:
    scenario: str
    name: str
    description: str
    columns: str | None
    axes: list[Axis]
    cells: list[Cell]
    source: str = ""
    """The scenario as given (registered name or YAML path): what each run launches."""


def _level(spec: Any, path: str) -> Level:
    if spec is None:
        return Level()
    if isinstance(spec, list):
        return Level(variants=[str(v) for v in spec])
    if isinstance(spec, dict):
        sec = Section(spec, path)
        level = Level([str(v) for v in sec.get("variants", list, [])], dict(sec.get("set", dict, {})))
        sec.finish()
        return level
    raise ScenarioError(f"'{path}' must be a list of variants or a mapping {{variants, set}}, got {spec!r}")


def _numeric_axis(name: str, spec: dict, path: str) -> Axis:
    sec = Section(spec, path)
    values, sets, scales = sec.get("values", list, None), sec.get("set", list, []), sec.get("scale", list, [])
    sec.finish()
    if not values or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        raise ScenarioError(f"'{path}.values' must be a non-empty list of numbers, got {values!r}")
    if not (sets or scales):
        raise ScenarioError(f"'{path}' needs a list of keys in 'set' and/or 'scale'")
    levels = {
        f"{v:g}": Level(sets={k: v for k in sets}, scales={k: float(v) for k in scales}, value=float(v)) for v in values
    }
    return Axis(name, levels, numeric=True)


def _axis(name: str, spec: Any, path: str) -> Axis:
    if not isinstance(spec, dict) or not spec:
        raise ScenarioError(f"'{path}' must be a non-empty mapping of levels (or values/set/scale)")
    if "values" in spec:
        return _numeric_axis(name, spec, path)
    return Axis(name, {str(label): _level(level, f"{path}.{label}") for label, level in spec.items()})


def _cell(
    base: dict, path: str, axes: list[Axis], labels: tuple[str, ...], cli: list[str], common: Mapping[str, Any]
) -> Cell:
    """Resolve one cell: placeholders, variants (validated), the grid's and its levels' set and scale overrides,
    command-line overrides."""
    by_axis = {a.name: lab for a, lab in zip(axes, labels)}
    variants, sets, scales = [], dict(common), {}
    for axis, label in zip(axes, labels):
        level = axis.levels[label]
        where = f"{path}.axes.{axis.name}.{label}"
        for v in level.variants:
            unknown = [p for p in PLACEHOLDER.findall(v) if p not in by_axis]
            if unknown:
                raise ScenarioError(
                    f"'{where}': variant '{v}' names unknown axis {{{unknown[0]}}}; axes: {', '.join(by_axis)}"
                )
            name = v.format_map(by_axis)
            if name not in (base.get("variants") or {}):
                raise ScenarioError(
                    f"'{where}': unknown variant '{name}'; allowed: {', '.join(sorted(base.get('variants') or {}))}"
                )
            variants.append(name)
        sets.update(level.sets)
        scales.update(level.scales)
    cfg = apply_overrides(select_variant(base, ",".join(variants)), override_strings(sets))
    scaled = {k: lookup(cfg, k) * f for k, f in scales.items() if isinstance(lookup(cfg, k), (int, float))}
    overrides = override_strings(sets) + override_strings(scaled)
    values = {a.name: a.levels[lab].value for a, lab in zip(axes, labels)}
    cell = Cell(by_axis, values, variants, overrides + list(cli), apply_overrides(cfg, override_strings(scaled) + cli))
    if scales and not scaled:
        raise ScenarioError(f"'{path}': cell {cell.id} has none of the keys to scale {sorted(scales)}")
    return cell


def load_grid(scenario: str, name: str, cli_overrides: list[str] = ()) -> Grid:
    """Read and resolve a grid of the scenario's ``sweeps`` section (no run, no validation of the builders)."""
    base = load_scenario(scenario)
    sweeps = base.get("sweeps") or {}
    if name not in sweeps:
        raise ScenarioError(
            f"unknown grid '{name}' in scenario '{base['scenario']}'; "
            f"available: {', '.join(sweeps) or 'none (no sweeps section)'}"
        )
    path = f"sweeps.{name}"
    sec = Section(sweeps[name], path)
    axes_spec = sec.get("axes", dict, {})
    if not axes_spec:
        raise ScenarioError(f"'{path}' must be a mapping with a non-empty 'axes' mapping")
    description = str(sec.get("description", str, ""))
    columns = sec.get("columns", str, None)
    common = dict(sec.get("set", dict, {}))
    sec.finish()
    axes = [_axis(str(a), s, f"{path}.axes.{a}") for a, s in axes_spec.items()]
    if columns is not None and columns not in axes_spec:
        raise ScenarioError(f"'{path}.columns' must name an axis ({', '.join(axes_spec)}), got {columns!r}")
    cells = [
        _cell(base, path, axes, labels, list(cli_overrides), common)
        for labels in itertools.product(*[list(a.levels) for a in axes])
    ]
    scaled_keys = {k for a in axes for lev in a.levels.values() for k in lev.scales}
    for key in sorted(scaled_keys):
        if all(lookup(c.cfg, key) is None for c in cells):
            raise ScenarioError(f"'{path}': no cell has the key to scale '{key}'")
    return Grid(base["scenario"], name, description, columns, axes, cells, scenario)


def distinct_truths(grid: Grid) -> list[tuple[str, dict]]:
    """(label, config) of each distinct truth (chief, deputy) of the grid, labelled by the axes that change it."""

    def truth(cell: Cell) -> str:
        return json.dumps(cell.cfg.get("truth"), sort_keys=True, default=str)

    def changes_truth(axis: Axis) -> bool:
        """Cells differing from the first cell in this axis only have different truths."""
        line = [
            c
            for c in grid.cells
            if all(c.labels[b.name] == grid.cells[0].labels[b.name] for b in grid.axes if b is not axis)
        ]
        return len({truth(c) for c in line}) > 1

    varying = [a.name for a in grid.axes if changes_truth(a)]
    seen: dict[str, tuple[str, dict]] = {}
    for c in grid.cells:
        seen.setdefault(truth(c), (", ".join(f"{a}={c.labels[a]}" for a in varying) or "all cells", c.cfg))
    return list(seen.values())


def validate(grid: Grid, seed0: int) -> None:
    """Build every cell's run (truth, sensors, filters, models) once; raises ScenarioError naming the cell."""
    with tempfile.TemporaryDirectory() as tmp:
        for cell in grid.cells:
            try:
                prepare_run(grid.scenario, Path(tmp) / cell.id, seed=seed0, cfg=cell.cfg)
            except ScenarioError as err:
                raise ScenarioError(f"grid '{grid.name}', cell {cell.id}: {err}") from err


def run_dir(out: Path, cell: Cell, i: int) -> Path:
    return out / cell.id / f"run_{i:03d}"


def cell_record(grid: Grid, cell: Cell) -> dict:
    """The JSON description of a cell (its score is added when it has run): its estimators with their dynamics
    model and sigma_accel (for a filter; None for the others)."""
    estimators = {}
    for name in resolve_estimators(cell.cfg, None):
        dyn = filter_key(cell.cfg, name, "dynamics") if "dynamics" in filter_config(cell.cfg, name) else None
        estimators[name] = {
            "model": dyn.model if dyn else None,
            "sigma_accel": getattr(dyn.options, "sigma_accel", None) if dyn else None,
        }
    found = study(grid.scenario)
    paper = found.sweep_case(cell.cfg) if found and found.sweep_case else None
    return {
        "id": cell.id,
        "labels": cell.labels,
        "values": cell.values,
        "variants": cell.variants,
        "overrides": cell.overrides,
        "estimators": estimators,
        "paper": paper,
    }


def reusable(out: Path, grid: Grid, runs: int, seed0: int, resume: bool) -> set[tuple[str, int]]:
    """(cell id, run) of the complete runs already in ``out`` (resume; an incomplete run there is removed to
    be run again: bench_engine.batch.reusable_run); raises ScenarioError if a run there was made with another
    configuration or holds foreign messages, or if ``out`` holds runs without resume."""
    done = set()
    for cell in grid.cells:
        for i in range(runs):
            try:
                if reusable_run(run_dir(out, cell, i), {**cell.cfg, "seed": seed0 + i}, resume):
                    done.add((cell.id, i))
            except ScenarioError as err:
                raise ScenarioError(f"cell {cell.id}, run {i}: {err}") from err
    return done


@dataclass
class SweepRun:
    """Every cell's runs (except those ``done``) through bench_engine.batch, each cell scored when its last run
    ends. After ``run()``: ``records`` (cell id -> JSON record with its score), ``series`` (cell id -> plot
    series), ``failures`` and ``reruns`` (runs repeated after cross-talk), as messages."""

    grid: Grid
    out: Path
    runs: int
    seed0: int = 1
    done: set = field(default_factory=set)
    records: dict = field(default_factory=dict)
    series: dict = field(default_factory=dict)
    failures: list = field(default_factory=list)
    reruns: list = field(default_factory=list)

    def __post_init__(self) -> None:
        self.specs = {
            (c.id, i): RunSpec(
                self.grid.source,
                run_dir(self.out, c, i),
                self.seed0 + i,
                variant=",".join(c.variants) or None,
                overrides=list(c.overrides),
            )
            for c in self.grid.cells
            for i in range(self.runs)
            if (c.id, i) not in self.done
        }
        self.remaining = {c.id: sum(1 for cid, _ in self.specs if cid == c.id) for c in self.grid.cells}
        self.records = {c.id: cell_record(self.grid, c) for c in self.grid.cells}

    def score(self, cell: Cell) -> None:
        bags = [
            b for b in (run_dir(self.out, cell, i) / "bag" for i in range(self.runs)) if (b / "metadata.yaml").is_file()
        ]
        if not bags:
            self.failures.append(f"cell {cell.id}: no run produced a bag")
            return
        try:
            scored, series = score_bags(bags, with_series=True)
        except Exception as err:  # a bad bag must not lose the other cells' results
            self.failures.append(f"cell {cell.id}: scoring failed ({type(err).__name__}: {err})")
            return
        self.records[cell.id].update(runs_ok=len(bags), score=scored)
        self.series[cell.id] = series or {}

    def _finished(self, result: RunResult) -> None:
        cell_id = next(cid for (cid, _), spec in self.specs.items() if spec is result.spec)
        self.reruns += result.reruns
        if not result.ok:
            error = f", {result.error}" if result.error else ""
            self.failures.append(f"{result.spec.out} (exit {result.code}{error}, log {result.spec.log})")
        self.remaining[cell_id] -= 1
        if self.remaining[cell_id] == 0:
            self.score(next(c for c in self.grid.cells if c.id == cell_id))

    def run(self, jobs: int, domains: list[int] | None = None, scheduler: str | None = None, retries: int = 2) -> None:
        """Run the remaining runs with the local executor, or on a Dask cluster (``scheduler``: an address or
        ``"local"``; bench_engine.executors)."""
        for cell in self.grid.cells:
            if self.remaining[cell.id] == 0:
                self.score(cell)
        if self.specs:
            run_batch(
                list(self.specs.values()),
                jobs,
                domains,
                f"{self.grid.scenario}/{self.grid.name}",
                on_done=self._finished,
                scheduler=scheduler,
                retries=retries,
            )


def write_outputs(sweep_run: SweepRun, header: dict) -> dict:
    """Write OUT/sweep.json and OUT/table.md (the study's sweep report, or a generic one) with its plots;
    ``header`` holds the run's settings (runs_per_cell, seed0, jobs, wall_s, runs_reused, command)."""
    grid = sweep_run.grid
    found = study(grid.scenario)
    extra_rows, extra_md = found.sweep_extra(distinct_truths(grid)) if found and found.sweep_extra else ([], "")
    sweep = json_ready(
        {
            "scenario": grid.scenario,
            "grid": grid.name,
            "description": grid.description,
            "columns": grid.columns,
            **header,
            "axes": {a.name: {"labels": list(a.levels), "numeric": a.numeric} for a in grid.axes},
            "cells": [sweep_run.records[c.id] for c in grid.cells],
            "failures": sweep_run.failures,
            "crosstalk_reruns": sweep_run.reruns,
            "extra": extra_rows,
        }
    )
    (sweep_run.out / "sweep.json").write_text(json.dumps(sweep, indent=1, allow_nan=False))
    if found and found.sweep_report:
        found.sweep_report(sweep_run.out, sweep, sweep_run.series, extra_md)
    else:
        generic_sweep_report(sweep_run.out, sweep)
    return sweep


def sweep_intro(sweep: Mapping, each_run: str = "") -> str:
    """The opening text of a study's sweep report: description, grid size, seeds, wall time, command and any
    failures (``each_run``, e.g. ", one day each", is added after the seeds)."""
    seeds = f"{sweep['seed0']}..{sweep['seed0'] + sweep['runs_per_cell'] - 1}"
    text = (
        f"{sweep.get('description', '')}\n\nGrid '{sweep['grid']}': {len(sweep['cells'])} cells x "
        f"{sweep['runs_per_cell']} runs (seeds {seeds}, the same in every cell){each_run}; wall time "
        f"{sweep['wall_s']:.0f} s with {sweep['jobs']} jobs.\n\nCommand: `{sweep['command']}`"
    )
    if sweep.get("failures"):
        text += "\n\nFailures:\n\n" + "\n".join(f"- {f}" for f in sweep["failures"])
    return text


def generic_sweep_report(out: Path, sweep: dict) -> Path:
    """table.md of a study without a sweep report: every cell's scalar scores (bench_eval.report)."""
    sections = [ReportSection(f"{sweep['scenario']} — sweep '{sweep['grid']}'", sweep.get("description", ""))]
    for cell in sweep["cells"]:
        if cell.get("score"):
            sections += generic_sections(cell["id"], cell["score"]["estimators"], None, None)
    return render(out, sections, f"Sweep {sweep['scenario']} / {sweep['grid']}", filename="table.md")
