"""Regenerate every result table the documentation shows: each study's declared tables (its folder's
tables.yaml) and the repository's own (docs/tables/*.yaml: the demo's report, the speed benchmarks), each by its
own command at the documented run counts, one after the other, locally or on a Dask cluster
(--scheduler, passed to the commands that take it). Writes results/RESULTS.md and results/results.json with
the commit, the machine (CPUs, model, load), and each table's command, wall time, load and Markdown. --resume skips
a table already complete for the same commit and arguments, and resumes the runs of an interrupted batch.
A table declared on_demand (a benchmark of the whole machine, longer than the others together: five fresh-clone
make test, scoring a 20-run Monte Carlo three ways) runs only when --only names it; the record keeps its last
result. --mini runs the miniature (one run per cell, shortened runs) into runs/reproduce-mini, to prove every table
has a working generator; --check only validates every command (script, flags, overrides) without running;
--docs rewrites the generated blocks of README.md and the docs/ pages from the record.

Examples:
  .venv/bin/python scripts/reproduce.py                       # every table (long: an idle machine helps)
  .venv/bin/python scripts/reproduce.py --only speed.fresh_clone  # an on-demand table
  .venv/bin/python scripts/reproduce.py --resume --only leo_radar.montecarlo,star_tracker.bound
  .venv/bin/python scripts/reproduce.py --scheduler tcp://HEAD:8786 --work /shared/reproduce
  .venv/bin/python scripts/reproduce.py --mini
  .venv/bin/python scripts/reproduce.py --only speed.filters,speed.graph
  .venv/bin/python scripts/reproduce.py --docs                # the pages' result tables from results/results.json
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from bench_engine import (
    launcher,  # noqa: E402
    plugins,  # noqa: E402
)
from bench_engine.cli.guard import ArgumentParser, check_writable, exit_codes, run_main, writing  # noqa: E402
from bench_engine.cli.options import names  # noqa: E402
from bench_engine.config import ScenarioError, apply_overrides, load_scenario, select_variant  # noqa: E402
from bench_engine.graph import resolve_estimators  # noqa: E402
from bench_eval import reproduce as rp  # noqa: E402
from bench_eval.study import study  # noqa: E402

EPILOG = exit_codes(
    c0="every chosen table was produced (or was already complete with --resume); the record is written",
    c1="a table's command failed (its log named); the others still ran and the record says which failed",
    c2="bad input: an unknown table, a declared command that does not validate (--check), no scripts/ folder",
)


DECLARED = "docs/tables"
"""The repository's own generated tables, one YAML file per group (its stem prefixes the tables' names)."""


def declared_tables(root: Path) -> list[rp.Table]:
    """Every registered study's tables, in the studies' registration order, then the repository's own
    (root/DECLARED/*.yaml, in name order)."""
    own = sorted((Path(root) / DECLARED).glob("*.yaml"))
    return [t for name in plugins.names("studies") for t in study(name).tables] + [
        t for path in own for t in rp.read_tables(path, path.stem)
    ]


def validate(table: rp.Table, root: Path, mini: bool, helps: dict[str, str]) -> list[str]:
    """Problems with a table's command, without running it: a missing script, a flag its --help does not
    list, a scenario that its --variant, --set overrides and --estimators make invalid (bench_engine.launcher's
    validate: every key and value of the run checked)."""
    script = root / "scripts" / table.script
    if not script.is_file():
        return [f"{table.name}: no script {script}"]
    if table.script not in helps:
        res = subprocess.run([sys.executable, str(script), "--help"], capture_output=True, text=True, cwd=root)
        helps[table.script] = res.stdout if res.returncode == 0 else ""
    text, args = helps[table.script], rp.arguments(table, mini)
    wanted = (
        rp.flags(args)
        + [f for f in (table.out_flag,) if f]
        + ["--scheduler"] * table.scheduler
        + ["--resume"] * table.resume
    )
    problems = [f"{table.name}: {table.script} --help lists no {f}" for f in wanted if f not in text]
    if table.scenario:
        try:
            cfg = apply_overrides(
                select_variant(load_scenario(table.scenario), rp.value(args, "--variant")), rp.overrides(args)
            )
            chosen = names(rp.value(args, "--estimators") or rp.value(args, "--filters"))  # --filters: old name
            launcher.validate(cfg, resolve_estimators(cfg, chosen), "truth")
        except ScenarioError as err:
            problems.append(f"{table.name}: {table.scenario} rejects its settings: {err}")
    return problems


def run_table(
    table: rp.Table, root: Path, work: Path, head: str, mini: bool, scheduler: str | None, resume: bool
) -> dict:
    """Run one table's command; its log and output directory under work/NAME. With --resume, a command that
    resumes keeps the runs already in its output directory if they were made at the same commit with the same
    arguments (work/NAME/made_by.json); otherwise the directory is emptied first, so that no table mixes runs
    of two commits. Returns its record entry (without the commit)."""
    out, ident = work / table.name, rp.identity(table, mini)
    made_by = {"commit": head, "identity": ident}
    keep = resume and table.resume and rp.read_results(out / "made_by.json") == made_by
    if (out / "out").exists() and not keep:
        shutil.rmtree(out / "out")
    out.mkdir(parents=True, exist_ok=True)
    (out / "made_by.json").write_text(json.dumps(made_by) + "\n")
    cmd = rp.command(table, sys.executable, root, out / "out", mini, scheduler, keep)
    print(f"[reproduce] {table.name}: {' '.join(cmd[1:])}", file=sys.stderr, flush=True)
    load, start = rp.load_average(), time.perf_counter()
    with open(out / "stdout.txt", "w") as stdout, open(out / "stderr.txt", "w") as stderr:
        code = subprocess.run(cmd, cwd=root, stdout=stdout, stderr=stderr).returncode
    wall = time.perf_counter() - start
    source = out / "stdout.txt" if table.markdown == rp.STDOUT else out / "out" / table.markdown
    markdown = source.read_text() if source.is_file() else ""
    ok = code == 0 and bool(markdown.strip())
    if table.text:
        markdown = f"```\n{markdown.rstrip()}\n```\n"
    status = "ok" if ok else f"FAILED (exit {code}; log {out / 'stderr.txt'})"
    print(f"[reproduce] {table.name}: {status} in {wall:.0f} s", file=sys.stderr, flush=True)
    return {
        "title": table.title,
        "status": "ok" if ok else f"failed (exit {code})",
        "wall_s": round(wall, 1),
        "load_average": load,
        "machine": {k: v for k, v in rp.machine().items() if k in ("cpus", "cpu_model")},
        "identity": ident,
        "markdown": markdown,
        "log": str(out / "stderr.txt"),
    }


def write_record(results: Path, record: dict, order: list[str]) -> None:
    """results.json and RESULTS.md (bench_eval.reproduce.render) under results/."""
    with writing(results):
        (results / "results.json").write_text(json.dumps(record, indent=1) + "\n")
        (results / "RESULTS.md").write_text(rp.render(record, order))


def copy_figures(table: rp.Table, root: Path, work: Path, entry: dict) -> None:
    """Copy a table's figures from its output directory (work/NAME/out) into the repository (rp.figure_path),
    when that directory holds the run the record's entry describes (work/NAME/made_by.json: same commit and
    arguments). A figure with neither a matching source nor a copy raises ExcerptError."""
    made_by = rp.read_results(work / table.name / "made_by.json")
    current = made_by == {"commit": entry.get("commit"), "identity": entry.get("identity")}
    for figure in table.figures:
        source, target = work / table.name / "out" / figure, root / rp.figure_path(table, figure)
        if current and source.is_file():
            with writing(target.parent):
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(source, target)
        elif not target.is_file():
            raise rp.ExcerptError(
                f"{table.name}: no figure {figure} from its recorded run in {work}: run the "
                "table again (scripts/reproduce.py --only " + table.name + ")"
            )


def write_pages(root: Path, record_path: Path, tables: list[rp.Table], work: Path) -> str:
    """Rewrite the generated blocks of README.md and every docs/ page from a full record, and copy the figures
    they show from the work directory; returns what was done, in one line. Raises ExcerptError for a block that
    cannot be filled, or a declared table that no page shows."""
    record = rp.read_results(record_path)
    if record.get("mini") or not record.get("tables"):
        raise rp.ExcerptError(f"{record_path} holds no full reproduction: run scripts/reproduce.py first")
    for table in tables:
        if table.figures and table.name in record["tables"]:
            copy_figures(table, root, work, record["tables"][table.name])
    by_name, shown, changed = {t.name: t for t in tables}, [], []
    for page in rp.pages(root):
        text = page.read_text(encoding="utf-8")
        try:
            new = rp.fill_page(text, record, by_name, rp.to_root(root, page))
        except rp.ExcerptError as err:
            raise rp.ExcerptError(f"{page.relative_to(root)}: {err}") from err
        shown += rp.block_names(new)
        if new != text:
            with writing(page.parent):
                page.write_text(new, encoding="utf-8")
            changed.append(str(page.relative_to(root)))
    unshown = sorted(set(by_name) - set(shown))
    if unshown:
        raise rp.ExcerptError(
            f"no page shows the declared table(s) {unshown}: add a block "
            "<!-- results: TABLE --><!-- /results --> where each belongs"
        )
    return f"{len(shown)} generated block(s) from {record_path}; " + (
        f"changed: {', '.join(changed)}" if changed else "every page unchanged"
    )


def main(argv: list[str] | None = None) -> int:
    """Validate or run the chosen tables and write the record; the exit codes of EPILOG."""
    p = ArgumentParser(description=__doc__, epilog=EPILOG)
    p.add_argument(
        "--only",
        help="comma-separated table names (default: every declared table but the on-demand ones; see --list)",
    )
    p.add_argument("--list", action="store_true", help="print the declared tables and their commands, then exit")
    p.add_argument("--check", action="store_true", help="validate every chosen table's command, run nothing")
    p.add_argument(
        "--docs",
        action="store_true",
        help="rewrite the generated blocks (<!-- results: TABLE --> ... <!-- /results -->) of README.md and "
        "the docs/ pages from the record (results/results.json), run nothing",
    )
    p.add_argument("--mini", action="store_true", help="the miniature: one run per cell, shortened runs")
    p.add_argument("--resume", action="store_true", help="skip tables complete for this commit and arguments")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS", help="Dask scheduler for the commands that take it")
    p.add_argument(
        "--results",
        type=Path,
        default=None,
        help="where RESULTS.md and results.json go (default results/, with --mini runs/reproduce-mini)",
    )
    p.add_argument(
        "--work",
        type=Path,
        default=None,
        help="the commands' output directories and logs (default runs/reproduce[-mini])",
    )
    p.add_argument("--root", type=Path, default=Path.cwd(), help="the repository (default: the current directory)")
    args = p.parse_args(argv)
    root = args.root.resolve()
    if not (root / "scripts").is_dir():
        p.error(f"{root} has no scripts/ folder: run from the repository or pass --root")
    declared = declared_tables(root)
    tables, names = declared, [t.name for t in declared]
    if len(set(names)) != len(names):
        p.error(f"duplicate table names: {sorted(n for n in set(names) if names.count(n) > 1)}")
    if args.only:
        chosen = [n for n in args.only.split(",") if n]
        unknown = sorted(set(chosen) - set(names))
        if unknown:
            p.error(f"unknown table(s) {unknown}; declared: {names}")
        tables = [t for t in tables if t.name in chosen]
    if args.list:
        for t in tables:
            demand = " (on demand: run when --only names it)" if t.on_demand else ""
            print(f"{t.name}: {t.title}{demand}\n  {' '.join(rp.identity(t, args.mini))}")
        return 0
    if args.check:
        helps: dict[str, str] = {}
        problems = [msg for t in tables for msg in validate(t, root, args.mini, helps)]
        print("\n".join(problems) if problems else f"{len(tables)} table command(s) validate")
        return 2 if problems else 0
    suffix = "reproduce-mini" if args.mini else "reproduce"
    results = args.results or (root / ("runs/" + suffix if args.mini else rp.RESULTS_DIR))
    work = args.work or root / "runs" / suffix
    if args.docs:
        if args.mini:
            p.error("--docs shows the full tables: leave out --mini")
        try:
            print(write_pages(root, results / "results.json", declared, work))
        except rp.ExcerptError as err:
            p.error(str(err))
        return 0
    if not args.only and not args.mini:
        waiting = [t.name for t in tables if t.on_demand]
        tables = [t for t in tables if not t.on_demand]
        if waiting:
            print(f"[reproduce] on demand, not run (name them with --only): {', '.join(waiting)}", file=sys.stderr)
    check_writable(results)
    check_writable(work)
    record = rp.read_results(results / "results.json")
    if record.get("mini", args.mini) != args.mini:  # never mix miniature and full tables in one record
        record = {"tables": {}}
    head = rp.commit(root)
    record.update(commit=head, machine=rp.machine(), mini=args.mini)
    start, failed = time.perf_counter(), []
    for t in tables:
        if args.resume and rp.is_complete(record["tables"].get(t.name), head, rp.identity(t, args.mini)):
            print(f"[reproduce] {t.name}: complete for {head[:12]}, skipped", file=sys.stderr)
            continue
        entry = run_table(t, root, work, head, args.mini, args.scheduler, args.resume)
        record["tables"][t.name] = {**entry, "commit": head}
        if entry["status"] == "ok" and not args.mini:
            try:
                copy_figures(t, root, work, record["tables"][t.name])
            except rp.ExcerptError as err:
                print(f"[reproduce] {err}", file=sys.stderr)
        if entry["status"] != "ok":
            failed.append(t.name)
        record["wall_s"] = round(time.perf_counter() - start, 1)
        write_record(results, record, names)  # after every table: an interrupted reproduction keeps what it did
    record["wall_s"] = round(time.perf_counter() - start, 1)
    write_record(results, record, names)
    print(
        f"[reproduce] {len(tables) - len(failed)}/{len(tables)} table(s) ok in {record['wall_s']:.0f} s; "
        f"{results / 'RESULTS.md'}" + (f"; failed: {', '.join(failed)}" if failed else ""),
        file=sys.stderr,
    )
    return 1 if failed else 0


def command() -> None:
    """Console script ``bench_reproduce``: ``main`` with its failures told in one line (bench_engine.cli.guard)."""
    sys.exit(run_main(main))
