"""The documentation's generated result tables as data, and the record of their reproduction
(scripts/reproduce.py).

Each study declares the tables its documentation page shows in its own folder (``tables.yaml``, read into its
Study's ``tables``); the repository's other generated tables (the demo's report, the speed benchmarks) are
declared in ``docs/tables/*.yaml``. A declaration names the script of scripts/ that produces the table, its
arguments at the documented run counts, where its Markdown lands (the command's standard output or a file under
its output directory), whether it takes ``--scheduler`` and ``--resume``, and its miniature (flag values
replaced, e.g. ``--runs 1``, and ``--set`` overrides that shorten the runs). Nothing here names a study.

The record (``RESULTS.md`` + ``results.json``) holds the commit, the machine and, per table, the command, its
wall time and its Markdown; a table whose entry is complete for the same commit and command is skipped on
``--resume``. A documentation page (Markdown) shows a table in a generated block, ``<!-- results: TABLE -->``
… ``<!-- /results -->``, which ``fill_page`` rewrites from the record.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import re
import subprocess
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from bench_engine import yamlio
from bench_engine.config import ScenarioError, Section

STDOUT = "stdout"


@dataclass(frozen=True)
class Table:
    """One generated table of the documentation and the command that produces it."""

    name: str
    """Unique over all studies: ``STUDY.TABLE``."""
    title: str
    script: str
    """A script of the repository's scripts/ folder, e.g. ``montecarlo.py``."""
    args: tuple[str, ...]
    """Its arguments at the documented run counts (without the output directory, --scheduler, --resume)."""
    markdown: str = STDOUT
    """Where the table's Markdown is: ``stdout`` or a path under the output directory."""
    text: bool = False
    """The command prints plain text rather than Markdown: the record shows it as a code block."""
    out_flag: str | None = None
    """The flag that takes the output directory (e.g. ``--out``), if the command writes one."""
    scheduler: bool = False
    """The command takes ``--scheduler ADDRESS`` (a Dask cluster)."""
    resume: bool = False
    """The command takes ``--resume`` (keeps the finished runs of an interrupted batch)."""
    scenario: str | None = None
    """The scenario its ``--set`` overrides apply to (checked by ``validate``)."""
    mini_args: Mapping[str, str] = field(default_factory=dict)
    """In the miniature: flag -> value replacing the flag's value (e.g. ``--runs: 1``)."""
    mini_set: tuple[str, ...] = ()
    """In the miniature: ``--set KEY=VALUE`` overrides appended (e.g. a shorter ``time.duration``)."""
    captions: tuple[str, ...] = ()
    """What a page shows of the table's Markdown: for each text, the first bold caption line (``**…**``)
    containing it and the Markdown table or code block under it (``excerpt``); empty: all of it."""
    figures: tuple[str, ...] = ()
    """Figures the command writes (paths under its output directory) that a page shows under the table, from
    their copies in the repository (``figure_path``)."""
    on_demand: bool = False
    """Run only when ``--only`` names it (and in the miniature): a benchmark of the whole machine that takes longer
    than the other tables together (e.g. five fresh-clone ``make test``); the record keeps its last result."""


def read_tables(path: Path, study: str) -> tuple[Table, ...]:
    """A study's tables.yaml (a list under ``tables``), read strictly: an unknown or mistyped key raises
    ScenarioError naming the file."""
    path = Path(path)
    top = Section(yamlio.load(path.read_text(encoding="utf-8")) or {}, "")
    tables = []
    try:
        for i, raw in enumerate(top.get("tables", list, [])):
            s = Section(raw, f"tables[{i}]")
            mini = s.section("mini")
            tables.append(
                Table(
                    name=f"{study}.{s.get('name', str)}",
                    title=s.get("title", str),
                    script=s.get("script", str),
                    args=tuple(str(a) for a in s.get("args", list, [])),
                    markdown=s.get("markdown", str, STDOUT),
                    text=s.get("text", bool, False),
                    out_flag=s.get("out_flag", str, None),
                    scheduler=s.get("scheduler", bool, False),
                    resume=s.get("resume", bool, False),
                    scenario=s.get("scenario", str, None),
                    mini_args={str(k): str(v) for k, v in mini.get("args", dict, {}).items()},
                    mini_set=tuple(str(o) for o in mini.get("set", list, [])),
                    captions=tuple(str(c) for c in s.get("captions", list, [])),
                    figures=tuple(str(f) for f in s.get("figures", list, [])),
                    on_demand=s.get("on_demand", bool, False),
                )
            )
            mini.finish()
            s.finish()
        top.finish()
    except ScenarioError as err:
        raise ScenarioError(f"{path}: {err}") from err
    return tuple(tables)


def arguments(table: Table, mini: bool) -> list[str]:
    """The table's arguments, in the miniature with its flag values replaced and its overrides appended."""
    args = list(table.args)
    if mini:
        for flag, value in table.mini_args.items():
            if flag in args:
                args[args.index(flag) + 1] = value
            else:
                args += [flag, value]
        for override in table.mini_set:
            args += ["--set", override]
    return args


def command(
    table: Table,
    python: str,
    root: Path,
    out: Path,
    mini: bool = False,
    scheduler: str | None = None,
    resume: bool = False,
) -> list[str]:
    """The full command line of a table: its script under root/scripts, output directory, cluster, resume."""
    cmd = [python, str(root / "scripts" / table.script), *arguments(table, mini)]
    if table.out_flag:
        cmd += [table.out_flag, str(out)]
    if scheduler and table.scheduler:
        cmd += ["--scheduler", scheduler]
    if resume and table.resume:
        cmd += ["--resume"]
    return cmd


def identity(table: Table, mini: bool) -> list[str]:
    """What a finished table's result depends on besides the commit: its script and arguments (not the
    output directory, the cluster or --resume, which do not change the numbers)."""
    return [table.script, *arguments(table, mini)]


def flags(args: list[str]) -> list[str]:
    """The long options among a command's arguments."""
    return [a.split("=")[0] for a in args if a.startswith("--")]


def value(args: list[str], flag: str) -> str | None:
    """The value after a flag among a command's arguments, or None."""
    return args[args.index(flag) + 1] if flag in args[:-1] else None


def overrides(args: list[str]) -> list[str]:
    """The ``--set`` values among a command's arguments."""
    return [args[i + 1] for i, a in enumerate(args[:-1]) if a == "--set"]


RESULTS_DIR = "results"
"""The record's directory in the repository (RESULTS.md, results.json, figures/)."""


def commit(root: Path) -> str:
    """HEAD's hash, with ``+dirty-`` and a hash of ``git diff HEAD`` when tracked files other than the record
    (results/: what this command writes, which an earlier --only run has already changed) differ from it (the
    results are then not HEAD's, and a different edit gives a different identity)."""

    def git(*a: str) -> str:
        return subprocess.run(["git", "-C", str(root), *a], capture_output=True, text=True).stdout

    head = git("rev-parse", "HEAD").strip() or "unknown"
    diff = git("diff", "HEAD", "--", ".", f":(exclude){RESULTS_DIR}")
    return head + (f"+dirty-{hashlib.sha1(diff.encode()).hexdigest()[:12]}" if diff else "")


def load_average() -> list[float]:
    """This machine's load averages over 1, 5 and 15 min (empty where the OS has none)."""
    return [round(x, 2) for x in os.getloadavg()] if hasattr(os, "getloadavg") else []


def machine() -> dict:
    """CPU count, CPU model, load averages (1, 5, 15 min), OS and Python of this machine."""
    model = platform.processor() or ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {
        "cpus": os.cpu_count(),
        "cpu_model": model,
        "load_average": load_average(),
        "system": platform.platform(),
        "python": platform.python_version(),
    }


def read_results(path: Path) -> dict:
    """results.json, or an empty record."""
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return {"tables": {}}


def is_complete(entry: Mapping | None, head: str, ident: list[str]) -> bool:
    """A recorded table that need not run again: finished, same commit (and uncommitted edits), same script
    and arguments."""
    return (
        bool(entry) and entry.get("status") == "ok" and entry.get("commit") == head and entry.get("identity") == ident
    )


def demote(markdown: str) -> str:
    """A command's Markdown with its headings two levels down, to sit under its table's heading (``##``);
    code blocks untouched."""
    lines, fenced = [], False
    for line in markdown.splitlines():
        fenced ^= line.startswith("```")
        lines.append("##" + line if line.startswith("#") and not fenced else line)
    return "\n".join(lines)


def render(record: Mapping, order: list[str]) -> str:
    """RESULTS.md: the commit and machine, then every table (in the studies' order) with its command, wall
    time and the load average at its start."""
    m = record.get("machine", {})
    lines = [
        "# Results",
        "",
        "Generated by `scripts/reproduce.py`" + (" --mini" if record.get("mini") else "") + "; do not edit by hand.",
        "",
        f"- commit of the last invocation: `{record.get('commit')}`; the tables': "
        + ", ".join(
            f"`{c[:12]}` ({n} table{'s' * (n > 1)})"
            for c, n in Counter(e.get("commit", "?") for e in record["tables"].values()).most_common()
        ),
        f"- machine: {m.get('cpus')} CPUs, {m.get('cpu_model')}, load average {m.get('load_average')} "
        f"at the start; {m.get('system')}, Python {m.get('python')}",
        f"- wall time: {sum(e['wall_s'] for e in record['tables'].values()):.0f} s over the tables "
        f"({record.get('wall_s', 0):.0f} s in the last invocation; resumed tables keep their own)",
        "",
    ]
    if record.get("mini"):
        lines += [
            "The miniature (one run per cell, shortened runs): it proves every table has a working "
            "generator; its figures are not the documentation's.",
            "",
        ]
    for name in order:
        entry = record["tables"].get(name)
        if not entry:
            continue
        load = entry.get("load_average")
        lines += [
            f"## {entry['title']}",
            "",
            f"`{name}`: `{' '.join(entry['identity'])}`, "
            f"{entry['status']}, {entry['wall_s']:.0f} s"
            + (f" (load average {load} at its start)" if load else "")
            + f", commit `{entry['commit'][:12]}`",
            "",
        ]
        lines += [demote(entry.get("markdown", "")).rstrip(), ""]
    return "\n".join(lines).rstrip() + "\n"


class ExcerptError(ValueError):
    """A table's caption is not in its Markdown, or a page's block names no declared table."""


def excerpt(markdown: str, captions: tuple[str, ...]) -> str:
    """The parts of a command's Markdown a page shows: for each caption text, the first bold line containing
    it and the table (``|`` rows) or fenced code block that follows it; all of it when there are no captions.
    Raises ExcerptError naming a caption that is not there."""
    if not captions:
        return markdown.strip()
    lines, parts = markdown.splitlines(), []
    for caption in captions:
        at = next((i for i, line in enumerate(lines) if line.startswith("**") and caption in line), None)
        if at is None:
            raise ExcerptError(f"no bold caption containing {caption!r}")
        part, i = [lines[at], ""], at + 1
        while i < len(lines) and not lines[i].strip():
            i += 1
        if i < len(lines) and lines[i].startswith("```"):
            end = next((j for j in range(i + 1, len(lines)) if lines[j].startswith("```")), len(lines) - 1)
            part += lines[i : end + 1]
        else:
            while i < len(lines) and lines[i].startswith("|"):
                part.append(lines[i])
                i += 1
        parts.append("\n".join(part).rstrip())
    return "\n\n".join(parts)


BLOCK = re.compile(r"(<!-- results: (?P<name>[\w.]+) -->\n)(?P<body>.*?)(<!-- /results -->)", re.S)
"""A generated block of a page: ``<!-- results: TABLE -->`` … ``<!-- /results -->``."""

LOCAL_LINK = re.compile(r"\[([^\]]+)\]\(#[^)]*\)")
"""A link to a section of the command's own report (``[STUDY](#STUDY)``), meaningless on another page."""

FIGURES = f"{RESULTS_DIR}/figures"
"""Where the figures the pages show are kept, relative to the repository: FIGURES/TABLE/FILE."""


def figure_path(table: Table, figure: str) -> str:
    """The repository path of one of a table's figures."""
    return f"{FIGURES}/{table.name}/{Path(figure).name}"


def page_block(table: Table, entry: Mapping, to_root: str = "") -> str:
    """A generated block's body: the table's excerpt (links into the command's own report reduced to their
    text), its figures (``to_root``: the path from the page's folder to the repository, e.g. ``../../``) and where
    they come from (command, commit, wall time, load, machine)."""
    body = LOCAL_LINK.sub(r"\1", excerpt(entry.get("markdown", ""), table.captions))  # text tables: fenced already
    for figure in table.figures:
        body += f"\n\n![{table.name}: {Path(figure).name}]({to_root}{figure_path(table, figure)})"
    load, machine = entry.get("load_average"), entry.get("machine")
    source = (
        f"*Generated by `scripts/reproduce.py --docs` from `results/results.json` ({table.name}): "
        f"`{' '.join(entry['identity'])}`, commit `{entry['commit'][:12]}`, {entry['wall_s']:.0f} s"
        + (f", load average {load[0]} at its start" if load else "")
        + (f", {machine['cpus']} CPUs ({machine['cpu_model']})" if machine else "")
        + ".*"
    )
    return f"{body}\n\n{source}\n"


def not_run_block(table: Table) -> str:
    """The block of an on-demand table the record does not hold (yet): the command that fills it."""
    return f"*Not in the record yet: `scripts/reproduce.py --only {table.name}` runs it (on demand).*\n"


def block_names(text: str) -> list[str]:
    """The table names of a page's generated blocks, in order."""
    return [m.group("name") for m in BLOCK.finditer(text)]


def fill_page(text: str, record: Mapping, tables: Mapping[str, Table], to_root: str = "") -> str:
    """A page with every generated block rewritten from the record (``to_root`` as in ``page_block``). Raises
    ExcerptError for a block naming an undeclared table or one the record does not hold complete, unless the
    table is on demand: its block then says how to run it (:func:`not_run_block`)."""

    def body(m: re.Match) -> str:
        name = m.group("name")
        if name not in tables:
            raise ExcerptError(f"block names no declared table: {name}")
        entry = record.get("tables", {}).get(name)
        if (not entry or entry.get("status") != "ok") and tables[name].on_demand:
            return m.group(1) + not_run_block(tables[name]) + m.group(4)
        if not entry or entry.get("status") != "ok":
            raise ExcerptError(f"block {name}: results/results.json holds no complete run of it")
        try:
            return m.group(1) + page_block(tables[name], entry, to_root) + m.group(4)
        except ExcerptError as err:
            raise ExcerptError(f"block {name}: {err}") from err

    return BLOCK.sub(body, text)


def pages(root: Path) -> list[Path]:
    """The repository's pages that may hold generated blocks: README.md and every Markdown file under docs/
    (its build directory excepted)."""
    docs = sorted(p for p in (Path(root) / "docs").rglob("*.md") if "_build" not in p.parts)
    return [Path(root) / "README.md", *docs]


def to_root(root: Path, page: Path) -> str:
    """The relative path from a page's folder to the repository (``""`` at the top, ``../../`` two down)."""
    depth = len(Path(page).resolve().parent.relative_to(Path(root).resolve()).parts)
    return "../" * depth
