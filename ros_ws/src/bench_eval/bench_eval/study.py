"""A study, as the generic report, sweep and demo see it: registered in the entry-point group
``tracking_bench.studies`` by the package that holds it (bench_studies.<name>).

A study's folder holds its scenario (``scenario.yaml``, registered in ``tracking_bench.scenarios``), the
paper's numbers and claims as data (``paper.yaml``: ``paper`` and ``claims``, bench_eval.claims), its report
section and, optionally, its sweep report, the lookup of the paper's case for a sweep cell and the result
tables of its documentation page with their commands (``tables.yaml``, scripts/reproduce.py).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from bench_engine import plugins, yamlio
from bench_engine.config import ScenarioError, Section
from bench_eval.claims import read_claims
from bench_eval.reproduce import Table, read_tables


@dataclass(frozen=True)
class Study:
    name: str
    paper: Mapping = field(default_factory=dict)
    """The paper's published numbers (paper.yaml ``paper``)."""
    claims: list = field(default_factory=list)
    """The paper's claims (bench_eval.claims.Claim) with the rule and score that decide each (paper.yaml
    ``claims``)."""
    sections: Callable | None = None
    """(scenario, scored filters, series, paper) -> list of report Sections."""
    sweep_report: Callable | None = None
    """(out_dir, sweep, series, extra_markdown) -> Path of the sweep's table.md."""
    sweep_case: Callable[[Mapping], Mapping | None] | None = None
    """Resolved scenario of a sweep cell -> the paper's numbers for that case (or None)."""
    sweep_extra: Callable | None = None
    """(distinct truths [(label, cfg)]) -> (JSON rows, Markdown) appended to a sweep's report."""
    tables: tuple[Table, ...] = ()
    """The result tables of the study's documentation page and the command of each (bench_eval.reproduce.Table,
    read from its folder's tables.yaml by load_tables): what scripts/reproduce.py runs."""
    demo_runs: int = 1
    """Seeded runs of the study in ``make demo`` (bench_eval.cli.demo): as many as its claims need to be
    decided (bench_eval.claims) where its runs are cheap, within the demo's time budget."""


def load_paper(path: Path) -> tuple[Mapping, list]:
    """(paper numbers, claims) of a study's paper.yaml: ``paper`` (free-form numbers its report section reads)
    and ``claims`` (read strictly into bench_eval.claims.Claim; a bad claim raises ScenarioError naming the file
    and key)."""
    path = Path(path)
    top = Section(yamlio.load(path.read_text(encoding="utf-8")) or {}, "")
    paper = top.get("paper", dict, {})
    try:
        claims = read_claims(top.get("claims", list, []))
        top.finish()
    except ScenarioError as err:
        raise ScenarioError(f"{path}: {err}") from err
    return paper, claims


def load_tables(folder: Path, name: str) -> tuple[Table, ...]:
    """The tables a study's folder declares in tables.yaml (bench_eval.reproduce.read_tables), or none."""
    path = Path(folder) / "tables.yaml"
    return read_tables(path, name) if path.is_file() else ()


def study(name: str | None) -> Study | None:
    """The registered study of a scenario name, or None."""
    return plugins.load("studies", name) if name in plugins.names("studies") else None
