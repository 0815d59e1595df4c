#!/usr/bin/env python3
"""Parameter sweep: every cell of a grid through the ROS 2 graph, N seeded runs per cell, every bag kept.

Grids are declared in the scenario's ``sweeps`` section; a grid is the product of its axes, in order:

    sweeps:
      tables:
        description: free text
        columns: rho                 # optional: axis whose levels are the paper-style table's columns
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
cell has, or a cell with none of them, is an error). A cell applies its variants, then its ``set`` and
``scale`` overrides, then the command line's --set. Every cell is resolved and validated (scenario keys,
variants, filters, models) before the first run starts; an error names the offending grid, level or value.

Run i of every cell uses seed SEED0 + i (the same measurement noise realisations in every cell) and writes
OUT/CELL/run_NNN/bag; up to --jobs runs go in parallel, each on its own ROS_DOMAIN_ID, all nodes of a run in
one process. Each cell is scored with bench_eval.scoring.score_bags as soon as its runs are done.
Outputs: OUT/sweep.json (cells, scores with per-run values, model errors), OUT/table.md (paper-style tables
with the paper's numbers, Monte Carlo standard errors, significance of the model ordering, consistency,
model error) and its PNG plots.

Examples:
  .venv/bin/python scripts/sweep.py formation_cqkf --grid tables --runs 12 --jobs 2 --out runs/sweep-tables
  .venv/bin/python scripts/sweep.py formation_cqkf --grid interval --runs 4 --out runs/sweep-interval
  .venv/bin/python scripts/sweep.py formation_cqkf --grid noise --runs 2 --set time.duration=600
Exit code: 0 on success, 1 if a run or a cell's scoring failed, 2 for a bad grid/scenario/argument.
"""
from __future__ import annotations

import argparse
import itertools
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads: see bench_engine.launcher

from bench_engine.config import (ScenarioError, apply_overrides, load_scenario, override_strings,  # noqa: E402
                              select_variant)

LAUNCH = Path(__file__).resolve().parent / "launch.py"
PLACEHOLDER = re.compile(r"\{([^{}]*)\}")
CROSSTALK_RETRIES = 2
"""Times a run is repeated when another graph on its ROS domain published into it."""
CROSSTALK_EXIT = 3


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


def _level(spec: Any, path: str) -> Level:
    if spec is None:
        return Level()
    if isinstance(spec, list):
        return Level(variants=[str(v) for v in spec])
    if isinstance(spec, dict):
        unknown = sorted(set(spec) - {"variants", "set"})
        if unknown:
            raise ScenarioError(f"unknown key(s) {unknown} in '{path}'; allowed: set, variants")
        variants, sets = spec.get("variants") or [], spec.get("set") or {}
        if not isinstance(variants, list) or not isinstance(sets, dict):
            raise ScenarioError(f"'{path}': 'variants' must be a list and 'set' a mapping key: value")
        return Level([str(v) for v in variants], dict(sets))
    raise ScenarioError(f"'{path}' must be a list of variants or a mapping {{variants, set}}, got {spec!r}")


def _numeric_axis(name: str, spec: dict, path: str) -> Axis:
    unknown = sorted(set(spec) - {"values", "set", "scale"})
    if unknown:
        raise ScenarioError(f"unknown key(s) {unknown} in '{path}'; allowed: values, set, scale")
    values, sets, scales = spec.get("values"), spec.get("set") or [], spec.get("scale") or []
    if not isinstance(values, list) or not values or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        raise ScenarioError(f"'{path}.values' must be a non-empty list of numbers, got {values!r}")
    if not isinstance(sets, list) or not isinstance(scales, list) or not (sets or scales):
        raise ScenarioError(f"'{path}' needs a list of keys in 'set' and/or 'scale'")
    levels = {f"{v:g}": Level(sets={k: v for k in sets}, scales={k: float(v) for k in scales}, value=float(v))
              for v in values}
    return Axis(name, levels, numeric=True)


def _axis(name: str, spec: Any, path: str) -> Axis:
    if not isinstance(spec, dict) or not spec:
        raise ScenarioError(f"'{path}' must be a non-empty mapping of levels (or values/set/scale)")
    if "values" in spec:
        return _numeric_axis(name, spec, path)
    return Axis(name, {str(label): _level(level, f"{path}.{label}") for label, level in spec.items()})


def _lookup(cfg: dict, key: str) -> Any:
    node: Any = cfg
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    return node


def _cell(base: dict, path: str, axes: list[Axis], labels: tuple[str, ...], cli: list[str]) -> Cell:
    """Resolve one cell: placeholders, variants (validated), set and scale overrides, command-line overrides."""
    by_axis = {a.name: lab for a, lab in zip(axes, labels)}
    variants, sets, scales = [], {}, {}
    for axis, label in zip(axes, labels):
        level = axis.levels[label]
        where = f"{path}.axes.{axis.name}.{label}"
        for v in level.variants:
            unknown = [p for p in PLACEHOLDER.findall(v) if p not in by_axis]
            if unknown:
                raise ScenarioError(f"'{where}': variant '{v}' names unknown axis {{{unknown[0]}}}; "
                                    f"axes: {', '.join(by_axis)}")
            name = v.format_map(by_axis)
            if name not in (base.get("variants") or {}):
                raise ScenarioError(f"'{where}': unknown variant '{name}'; "
                                    f"allowed: {', '.join(sorted(base.get('variants') or {}))}")
            variants.append(name)
        sets.update(level.sets)
        scales.update(level.scales)
    cfg = apply_overrides(select_variant(base, ",".join(variants)), override_strings(sets))
    scaled = {k: _lookup(cfg, k) * f for k, f in scales.items() if isinstance(_lookup(cfg, k), (int, float))}
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
        raise ScenarioError(f"unknown grid '{name}' in scenario '{base['scenario']}'; "
                            f"available: {', '.join(sweeps) or 'none (no sweeps section)'}")
    spec, path = sweeps[name], f"sweeps.{name}"
    if not isinstance(spec, dict) or not isinstance(spec.get("axes"), dict) or not spec["axes"]:
        raise ScenarioError(f"'{path}' must be a mapping with a non-empty 'axes' mapping")
    unknown = sorted(set(spec) - {"description", "columns", "axes"})
    if unknown:
        raise ScenarioError(f"unknown key(s) {unknown} in '{path}'; allowed: axes, columns, description")
    axes = [_axis(str(a), s, f"{path}.axes.{a}") for a, s in spec["axes"].items()]
    columns = spec.get("columns")
    if columns is not None and columns not in spec["axes"]:
        raise ScenarioError(f"'{path}.columns' must name an axis ({', '.join(spec['axes'])}), got {columns!r}")
    cells = [_cell(base, path, axes, labels, list(cli_overrides))
             for labels in itertools.product(*[list(a.levels) for a in axes])]
    scaled_keys = {k for a in axes for lev in a.levels.values() for k in lev.scales}
    for key in sorted(scaled_keys):
        if all(_lookup(c.cfg, key) is None for c in cells):
            raise ScenarioError(f"'{path}': no cell has the key to scale '{key}'")
    return Grid(base["scenario"], name, str(spec.get("description", "")), columns, axes, cells)


def distinct_truths(grid: Grid) -> list[tuple[str, dict]]:
    """(label, config) of each distinct truth (chief, deputy) of the grid, labelled by the axes that change it."""
    def truth(cell: Cell) -> str:
        return json.dumps(cell.cfg.get("truth"), sort_keys=True, default=str)

    def changes_truth(axis: Axis) -> bool:
        """Cells differing from the first cell in this axis only have different truths."""
        line = [c for c in grid.cells if all(c.labels[b.name] == grid.cells[0].labels[b.name]
                                             for b in grid.axes if b is not axis)]
        return len({truth(c) for c in line}) > 1

    varying = [a.name for a in grid.axes if changes_truth(a)]
    seen: dict[str, tuple[str, dict]] = {}
    for c in grid.cells:
        seen.setdefault(truth(c), (", ".join(f"{a}={c.labels[a]}" for a in varying) or "all cells", c.cfg))
    return list(seen.values())


def validate(grid: Grid, seed0: int) -> None:
    """Build every cell's run (truth, sensors, filters, models) once; raises ScenarioError naming the cell."""
    from bench_engine.launcher import prepare_run
    with tempfile.TemporaryDirectory() as tmp:
        for cell in grid.cells:
            try:
                prepare_run(grid.scenario, Path(tmp) / cell.id, seed=seed0, cfg=cell.cfg)
            except ScenarioError as err:
                raise ScenarioError(f"grid '{grid.name}', cell {cell.id}: {err}") from err


def crosstalk(bag: Path, steps: int) -> bool:
    """True when the bag holds another number of truth messages than the run has steps: a graph on the same
    ROS domain (e.g. a run started elsewhere without --domain-id) published into this run's topics."""
    import yaml

    from bench_engine.graph import TRUTH_TOPIC
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    counts = {t["topic_metadata"]["name"]: t["message_count"] for t in info["topics_with_message_count"]}
    return counts.get(TRUTH_TOPIC) != steps


def run_dir(args: argparse.Namespace, cell: Cell, i: int) -> Path:
    return args.out / cell.id / f"run_{i:03d}"


def launch_command(args: argparse.Namespace, cell: Cell, i: int, domain: int) -> list[str]:
    cmd = [sys.executable, str(LAUNCH), args.scenario, "--seed", str(args.seed0 + i), "--out",
           str(run_dir(args, cell, i)), "--domain-id", str(domain), "--single-process", "--no-score"]
    if cell.variants:
        cmd += ["--variant", ",".join(cell.variants)]
    for o in cell.overrides:
        cmd += ["--set", o]
    return cmd


def cell_record(grid: Grid, cell: Cell) -> dict:
    """The JSON description of a cell (its score is added when it has run)."""
    from bench_engine.graph import filter_config, resolve_filters
    from bench_eval.report import paper004_case
    filters = {}
    for name in resolve_filters(cell.cfg, None):
        dyn = filter_config(cell.cfg, name).get("dynamics") or {}
        filters[name] = {"model": dyn.get("model"), "sigma_accel": dyn.get("sigma_accel")}
    paper = paper004_case(cell.cfg) if grid.scenario == "formation_cqkf" else None
    return {"id": cell.id, "labels": cell.labels, "values": cell.values, "variants": cell.variants,
            "overrides": cell.overrides, "filters": filters, "paper": paper}


def reusable(args: argparse.Namespace, grid: Grid) -> set[tuple[str, int]]:
    """(cell id, run) of the complete runs already in OUT (--resume); raises ScenarioError if a run there
    was made with another configuration or holds foreign messages, or if OUT holds runs without --resume."""
    import yaml

    from bench_engine.timegrid import build_time
    done = set()
    for cell in grid.cells:
        for i in range(args.runs):
            path = run_dir(args, cell, i)
            if not path.exists():
                continue
            if not args.resume:
                raise ScenarioError(f"{path} already exists: choose another --out, remove it, or give --resume")
            config = path / "bag" / "run_config.yaml"
            if not (path / "bag" / "metadata.yaml").is_file() or not config.is_file():
                raise ScenarioError(f"{path} is an incomplete run: remove it to run it again")
            if yaml.safe_load(config.read_text())["scenario"] != {**cell.cfg, "seed": args.seed0 + i}:
                raise ScenarioError(f"{path} was run with another configuration than cell {cell.id}, seed "
                                    f"{args.seed0 + i}: remove it or choose another --out")
            if crosstalk(path / "bag", build_time(cell.cfg).steps):
                raise ScenarioError(f"{path} holds messages of another graph: remove it to run it again")
            done.add((cell.id, i))
    return done


class Runner:
    """Runs every cell's runs (except those ``done``) in parallel and scores each cell when its last run ends.

    After ``run()``: ``records`` (cell id -> JSON record with its score), ``series`` (cell id -> plot
    series), ``failures`` and ``reruns`` (runs repeated after cross-talk), as messages.
    """

    def __init__(self, args: argparse.Namespace, grid: Grid, done: set[tuple[str, int]]) -> None:
        self.args, self.grid = args, grid
        self.tasks = [(c, i) for c in grid.cells for i in range(args.runs) if (c.id, i) not in done]
        self.remaining = {c.id: sum(1 for t in self.tasks if t[0] is c) for c in grid.cells}
        self.records = {c.id: cell_record(grid, c) for c in grid.cells}
        self.series: dict[str, dict] = {}
        self.failures: list[str] = []
        self.reruns: list[str] = []
        self.free_domains = list(range(args.domain_base, args.domain_base + args.jobs))

    def run_one(self, cell: Cell, i: int) -> tuple[Cell, int, int]:
        """Run i of a cell; a run another graph published into is set aside (RUN.crosstalkK) and run again."""
        from bench_engine.timegrid import build_time
        domain = self.free_domains.pop()
        path = run_dir(self.args, cell, i)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            for attempt in range(1 + CROSSTALK_RETRIES):
                with open(f"{path}.log", "w") as log:
                    code = subprocess.run(launch_command(self.args, cell, i, domain), stdout=log,
                                          stderr=subprocess.STDOUT).returncode
                if code != 0 or not crosstalk(path / "bag", build_time(cell.cfg).steps):
                    return cell, i, code
                path.rename(f"{path}.crosstalk{attempt}")
                self.reruns.append(f"cell {cell.id} run {i}: foreign messages on ROS domain {domain}, set aside "
                                   f"as {path.name}.crosstalk{attempt}")
            return cell, i, CROSSTALK_EXIT
        finally:
            self.free_domains.append(domain)

    def score(self, cell: Cell) -> None:
        from bench_eval.scoring import score_bags
        bags = [run_dir(self.args, cell, i) / "bag" for i in range(self.args.runs)]
        bags = [b for b in bags if (b / "metadata.yaml").is_file()]
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

    def finished(self, cell: Cell, i: int, code: int) -> None:
        if code == CROSSTALK_EXIT:
            self.failures.append(f"cell {cell.id} run {i}: foreign messages in all {1 + CROSSTALK_RETRIES} attempts")
        elif code != 0:
            self.failures.append(f"cell {cell.id} run {i} (exit {code}, log {run_dir(self.args, cell, i)}.log)")
        self.remaining[cell.id] -= 1
        if self.remaining[cell.id] == 0:
            self.score(cell)

    def run(self) -> None:
        from tqdm import tqdm
        for cell in self.grid.cells:
            if self.remaining[cell.id] == 0:
                self.score(cell)
        with ThreadPoolExecutor(self.args.jobs) as pool, tqdm(total=len(self.tasks), unit="run",
                                                              desc=f"{self.grid.scenario}/{self.grid.name}") as bar:
            for fut in as_completed([pool.submit(self.run_one, c, i) for c, i in self.tasks]):
                self.finished(*fut.result())
                bar.update()


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenario", help="scenario name or YAML path (with a 'sweeps' section)")
    p.add_argument("--grid", required=True, help="name of the grid in the scenario's 'sweeps' section")
    p.add_argument("--runs", type=int, default=1, help="Monte Carlo runs per cell (default 1)")
    p.add_argument("--jobs", type=int, default=2, help="runs in parallel (default 2)")
    p.add_argument("--out", type=Path, default=None, help="output directory (default runs/sweep-SCENARIO-GRID)")
    p.add_argument("--seed0", type=int, default=1, help="seed of run 0 of every cell (run i uses seed0 + i)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="scenario override applied to every cell after its own, repeatable")
    p.add_argument("--domain-base", type=int, default=60, help="job j uses ROS_DOMAIN_ID domain-base + j")
    p.add_argument("--resume", action="store_true",
                   help="keep the complete runs already in OUT (same configuration and seed), run the others")
    p.add_argument("--json", action="store_true", help="print sweep.json instead of the summary")
    args = p.parse_args(argv)
    if args.runs < 1 or args.jobs < 1:
        p.error("--runs and --jobs must be >= 1")
    if args.domain_base < 0 or args.domain_base + args.jobs - 1 > 101:
        p.error("--domain-base + --jobs - 1 must be in [0, 101] (ROS_DOMAIN_ID range)")
    return args


def write_outputs(args: argparse.Namespace, argv: list[str] | None, grid: Grid, runner: Runner, reused: int,
                  wall: float) -> dict:
    """Write OUT/sweep.json and OUT/table.md (with its plots and the grid's model-error table); returns the
    JSON content."""
    import model_error
    from bench_eval.metrics import json_ready
    from bench_eval.report import write_sweep_report
    sweep = json_ready({
        "scenario": grid.scenario, "grid": grid.name, "description": grid.description, "columns": grid.columns,
        "runs_per_cell": args.runs, "seed0": args.seed0, "jobs": args.jobs, "wall_s": round(wall, 1),
        "runs_reused": reused, "command": " ".join(["scripts/sweep.py"] + (sys.argv[1:] if argv is None else argv)),
        "axes": {a.name: {"labels": list(a.levels), "numeric": a.numeric} for a in grid.axes},
        "cells": [runner.records[c.id] for c in grid.cells], "failures": runner.failures,
        "crosstalk_reruns": runner.reruns,
        "model_error": [r for label, cfg in distinct_truths(grid) for r in model_error.model_error_rows(label, cfg)]})
    (args.out / "sweep.json").write_text(json.dumps(sweep, indent=1, allow_nan=False))
    write_sweep_report(args.out, sweep, runner.series, model_error.markdown(sweep["model_error"]))
    return sweep


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    args.out = args.out or Path(f"runs/sweep-{Path(args.scenario).stem}-{args.grid}")
    try:
        grid = load_grid(args.scenario, args.grid, args.overrides)
        validate(grid, args.seed0)
        done = reusable(args, grid)
    except ScenarioError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(f"[sweep] {grid.scenario}/{grid.name}: {len(grid.cells)} cells x {args.runs} runs "
          f"({len(done)} reused), {args.jobs} jobs, out {args.out}", file=sys.stderr)
    started = time.monotonic()
    runner = Runner(args, grid, done)
    runner.run()
    wall = time.monotonic() - started
    sweep = write_outputs(args, argv, grid, runner, len(done), wall)
    print(json.dumps(sweep, indent=1) if args.json else (args.out / "table.md").read_text())
    print(f"[sweep] {len(runner.tasks)} runs in {wall:.0f} s; table {args.out / 'table.md'}", file=sys.stderr)
    for r in runner.reruns:
        print(f"[sweep] ran again: {r}", file=sys.stderr)
    for f in runner.failures:
        print(f"[sweep] failed: {f}", file=sys.stderr)
    return 1 if runner.failures else 0


if __name__ == "__main__":
    sys.exit(main())
