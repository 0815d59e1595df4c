"""scripts/reproduce.py (bench_eval.reproduce, bench_eval.cli.reproduce): every table the studies and docs/tables
declare has a command that validates, in full and in the miniature, and the cheapest one runs end to end into the
record, which --resume then keeps; every page's generated blocks are the record's."""

import dataclasses
import json
import subprocess
from pathlib import Path

import pytest
from graph_helpers import ROOT

from bench_engine.config import ScenarioError
from bench_eval import reproduce as rp
from bench_eval.cli import reproduce as cli

CHEAPEST = "formation_cqkf.model_error"  # ~1 s in the miniature


def test_every_declared_table_validates_in_full_and_in_the_miniature():
    tables = cli.declared_tables(ROOT)
    groups = {t.name.split(".")[0] for t in tables}
    assert {"leo_radar", "formation_pf", "formation_cqkf", "grace_velocity", "star_tracker", "demo", "speed"} <= groups
    helps: dict[str, str] = {}
    problems = [msg for mini in (False, True) for t in tables for msg in cli.validate(t, ROOT, mini, helps)]
    assert problems == []


def test_validate_names_an_unknown_flag_and_a_bad_override():
    table = rp.Table(
        "x.y",
        "t",
        "bounds.py",
        ("leo_radar", "--no-such-flag", "1"),
        scenario="leo_radar",
        mini_set=("sensors.radar.no_such_key=1",),
    )
    problems = cli.validate(table, ROOT, True, {})
    assert any("--no-such-flag" in p for p in problems)
    assert any("rejects its settings" in p for p in problems)


def test_miniature_replaces_flag_values_and_appends_overrides():
    table = rp.Table(
        "s.t",
        "t",
        "sweep.py",
        ("s", "--runs", "10", "--jobs", "2"),
        out_flag="--out",
        scheduler=True,
        resume=True,
        mini_args={"--runs": "1", "--samples": "5"},
        mini_set=("time.duration=60",),
    )
    assert rp.arguments(table, False) == ["s", "--runs", "10", "--jobs", "2"]
    assert rp.arguments(table, True) == [
        "s",
        "--runs",
        "1",
        "--jobs",
        "2",
        "--samples",
        "5",
        "--set",
        "time.duration=60",
    ]
    cmd = rp.command(table, "py", Path("/r"), Path("/o"), True, "tcp://h:1", True)
    assert cmd[-5:] == ["--out", "/o", "--scheduler", "tcp://h:1", "--resume"]
    assert "--scheduler" not in rp.command(table, "py", Path("/r"), Path("/o"))
    assert rp.identity(table, True) == ["sweep.py", *rp.arguments(table, True)]


def test_tables_yaml_is_read_strictly(tmp_path):
    path = tmp_path / "tables.yaml"
    path.write_text("tables:\n- {name: a, title: A, script: launch.py, runs: 3}\n")
    with pytest.raises(ScenarioError, match="tables.yaml"):
        rp.read_tables(path, "s")
    path.write_text(
        "tables:\n- {name: a, title: A, script: launch.py, args: [s, --runs, 3], "
        "mini: {args: {--runs: 1}}, captions: [Table A]}\n"
    )
    (table,) = rp.read_tables(path, "s")
    assert table.name == "s.a" and table.args == ("s", "--runs", "3") and table.mini_args == {"--runs": "1"}
    assert table.captions == ("Table A",)


def test_complete_needs_success_same_commit_and_same_arguments():
    entry = {"status": "ok", "commit": "abc", "identity": ["a.py", "--runs", "1"]}
    assert rp.is_complete(entry, "abc", ["a.py", "--runs", "1"])
    assert not rp.is_complete(entry, "abd", ["a.py", "--runs", "1"])
    assert not rp.is_complete(entry, "abc", ["a.py", "--runs", "2"])
    assert not rp.is_complete({**entry, "status": "failed (exit 1)"}, "abc", ["a.py", "--runs", "1"])
    assert not rp.is_complete(None, "abc", [])


def test_headings_move_under_the_table_but_code_blocks_do_not():
    assert rp.demote("# A\n```\n# not a heading\n```\n## B") == "### A\n```\n# not a heading\n```\n#### B"


def test_cheapest_table_runs_in_the_miniature_and_resume_skips_it(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(rp, "commit", lambda root: "c0ffee")  # the shared tree's edits must not change it mid-test
    results, work = tmp_path / "results", tmp_path / "work"
    argv = ["--mini", "--only", CHEAPEST, "--results", str(results), "--work", str(work), "--root", str(ROOT)]
    assert cli.main(argv) == 0
    record = json.loads((results / "results.json").read_text())
    assert record["commit"] == "c0ffee" and record["mini"] is True
    assert record["machine"]["cpus"] >= 1 and len(record["machine"]["load_average"]) == 3
    entry = record["tables"][CHEAPEST]
    assert entry["status"] == "ok" and entry["wall_s"] > 0 and len(entry["load_average"]) == 3
    assert "|" in entry["markdown"]
    md = (results / "RESULTS.md").read_text()
    assert "c0ffee" in md and entry["title"] in md and entry["markdown"].strip().splitlines()[-1] in md
    capsys.readouterr()
    assert cli.main([*argv, "--resume"]) == 0
    assert "skipped" in capsys.readouterr().err
    assert json.loads((results / "results.json").read_text())["tables"][CHEAPEST] == entry
    monkeypatch.setattr(rp, "commit", lambda root: "beef")  # another commit: the table runs again
    assert cli.main([*argv, "--resume"]) == 0
    assert json.loads((results / "results.json").read_text())["tables"][CHEAPEST]["commit"] == "beef"


def test_resume_keeps_a_commands_runs_only_from_the_same_commit_and_arguments(tmp_path, monkeypatch):
    table = rp.Table("s.t", "t", "sweep.py", ("s", "--runs", "3"), out_flag="--out", resume=True)
    calls = []

    def fake_run(cmd, cwd, stdout, stderr):
        """The command: notes its arguments and whether it found the previous run's file; prints a table."""
        out = Path(cmd[cmd.index("--out") + 1])
        calls.append(("--resume" in cmd, (out / "run_000").exists()))
        out.mkdir(parents=True, exist_ok=True)
        (out / "run_000").write_text("")
        stdout.write("| a |\n|---|\n")
        return type("Done", (), {"returncode": 0})()

    monkeypatch.setattr(cli.subprocess, "run", fake_run)
    for head, resume in (("c1", False), ("c1", True), ("c2", True), ("c2", False)):
        entry = cli.run_table(table, ROOT, tmp_path, head, False, None, resume)
        assert entry["status"] == "ok" and entry["markdown"] == "| a |\n|---|\n"
    assert calls == [(False, False), (True, True), (False, False), (False, False)]


MARKDOWN = """# Report

**Table A: errors**

| a | b |
|---|---|
| 1 | 2 |

Some prose.

**Table B: the text form**

```
x  y
1  2
```

**Table C: unused**

| c |
|---|
"""


def test_excerpt_takes_each_captions_table_or_code_block_and_nothing_else():
    assert rp.excerpt(MARKDOWN, ()) == MARKDOWN.strip()
    part = rp.excerpt(MARKDOWN, ("Table B", "Table A"))
    table_b = "**Table B: the text form**\n\n```\nx  y\n1  2\n```"
    assert part == table_b + "\n\n**Table A: errors**\n\n| a | b |\n|---|---|\n| 1 | 2 |"
    with pytest.raises(rp.ExcerptError, match="'Table Z'"):
        rp.excerpt(MARKDOWN, ("Table Z",))


def test_fill_page_rewrites_only_the_generated_blocks_and_names_what_it_cannot_fill():
    table = rp.Table("s.t", "T", "x.py", ("s",), captions=("Table A",), figures=("report/a.png",))
    entry = {
        "status": "ok",
        "commit": "0123456789abcdef",
        "identity": ["x.py", "s"],
        "wall_s": 12.0,
        "load_average": [1.5, 1, 1],
        "machine": {"cpus": 2, "cpu_model": "CPU X"},
        "markdown": MARKDOWN.replace("errors**", "errors of [s](#s)**"),
    }
    page = "intro\n<!-- results: s.t -->\nstale | 9 |\n<!-- /results -->\noutro\n"
    filled = rp.fill_page(page, {"tables": {"s.t": entry}}, {"s.t": table}, "../../")
    assert filled.startswith("intro\n<!-- results: s.t -->\n**Table A: errors of s**") and filled.endswith(
        "<!-- /results -->\noutro\n"
    )  # the link into the command's own report is reduced to its text
    assert "stale" not in filled and "| 1 | 2 |" in filled and "`x.py s`, commit `0123456789ab`, 12 s" in filled
    assert "2 CPUs (CPU X)" in filled
    assert "![s.t: a.png](../../results/figures/s.t/a.png)" in filled
    assert rp.fill_page(filled, {"tables": {"s.t": entry}}, {"s.t": table}, "../../") == filled  # idempotent
    assert rp.block_names(filled) == ["s.t"]
    with pytest.raises(rp.ExcerptError, match="no declared table: s.u"):
        rp.fill_page(page.replace("s.t", "s.u"), {"tables": {"s.t": entry}}, {"s.t": table})
    with pytest.raises(rp.ExcerptError, match="no complete run"):
        rp.fill_page(page, {"tables": {"s.t": {**entry, "status": "failed (exit 1)"}}}, {"s.t": table})


def test_the_pages_result_tables_are_the_records():
    """The generated blocks of README.md and the docs/ pages are what scripts/reproduce.py --docs writes from
    results/results.json: every declared table on exactly one page, none edited by hand."""
    record = rp.read_results(ROOT / "results" / "results.json")
    assert record.get("tables") and not record.get("mini"), "results/results.json: run scripts/reproduce.py"
    tables = {t.name: t for t in cli.declared_tables(ROOT)}
    shown = []
    for page in rp.pages(ROOT):
        text = page.read_text(encoding="utf-8")
        shown += rp.block_names(text)
        assert rp.fill_page(text, record, tables, rp.to_root(ROOT, page)) == text, (
            f"{page.relative_to(ROOT)} is stale: run scripts/reproduce.py --docs"
        )
    assert sorted(shown) == sorted(tables)
    missing = [
        rp.figure_path(t, f) for t in tables.values() for f in t.figures if not (ROOT / rp.figure_path(t, f)).is_file()
    ]
    assert not missing, missing


def test_a_page_is_reached_from_the_repository_by_its_depth(tmp_path):
    assert rp.to_root(tmp_path, tmp_path / "README.md") == ""
    assert rp.to_root(tmp_path, tmp_path / "docs" / "studies" / "x.md") == "../../"
    (tmp_path / "docs" / "_build" / "x").mkdir(parents=True)
    (tmp_path / "docs" / "_build" / "x" / "page.md").write_text("built")
    (tmp_path / "docs" / "index.md").write_text("source")
    assert rp.pages(tmp_path) == [tmp_path / "README.md", tmp_path / "docs" / "index.md"]


def test_figures_are_copied_only_from_the_recorded_run(tmp_path):
    table = rp.Table("s.t", "T", "x.py", ("s",), figures=("report/plot.png",))
    work, root = tmp_path / "work", tmp_path / "repo"
    (work / "s.t" / "out" / "report").mkdir(parents=True)
    (work / "s.t" / "out" / "report" / "plot.png").write_bytes(b"png of commit c1")
    (work / "s.t" / "made_by.json").write_text(json.dumps({"commit": "c1", "identity": ["x.py", "s"]}))
    entry = {"commit": "c1", "identity": ["x.py", "s"]}
    cli.copy_figures(table, root, work, entry)
    copied = root / rp.figure_path(table, "report/plot.png")
    assert (
        copied.read_bytes() == b"png of commit c1"
        and rp.figure_path(table, "x/plot.png") == "results/figures/s.t/plot.png"
    )
    (work / "s.t" / "out" / "report" / "plot.png").write_bytes(b"png of another run")
    cli.copy_figures(table, root, work, {**entry, "commit": "c2"})  # not the recorded run: the copy stays
    assert copied.read_bytes() == b"png of commit c1"
    copied.unlink()
    with pytest.raises(rp.ExcerptError, match="no figure report/plot.png"):
        cli.copy_figures(table, root, work, {**entry, "commit": "c2"})


def test_pages_are_never_written_from_a_miniature_record(tmp_path, capsys):
    (tmp_path / "results.json").write_text(json.dumps({"mini": True, "tables": {CHEAPEST: {"status": "ok"}}}))
    before = (ROOT / "README.md").read_bytes()
    with pytest.raises(SystemExit) as stop:
        cli.main(["--docs", "--results", str(tmp_path), "--root", str(ROOT)])
    assert stop.value.code == 2 and "holds no full reproduction" in capsys.readouterr().err
    assert (ROOT / "README.md").read_bytes() == before


def test_the_commit_is_dirty_for_an_edited_source_not_for_the_record(tmp_path):

    def git(*a: str) -> None:
        subprocess.run(
            ["git", "-C", str(tmp_path), "-c", "user.email=t@t", "-c", "user.name=t", *a],
            check=True,
            capture_output=True,
        )

    (tmp_path / rp.RESULTS_DIR).mkdir()
    (tmp_path / rp.RESULTS_DIR / "results.json").write_text("{}")
    (tmp_path / "code.py").write_text("x = 1\n")
    git("init", "-q")
    git("add", ".")
    git("commit", "-qm", "c")
    head = rp.commit(tmp_path)
    assert len(head) == 40 and "+dirty" not in head
    (tmp_path / rp.RESULTS_DIR / "results.json").write_text('{"tables": {}}')  # an earlier --only run's record
    assert rp.commit(tmp_path) == head
    (tmp_path / "code.py").write_text("x = 2\n")
    assert rp.commit(tmp_path).startswith(head + "+dirty-")


def test_an_on_demand_table_runs_only_when_named_and_its_result_is_kept(tmp_path, monkeypatch, capsys):
    (tmp_path / "scripts").mkdir()
    (tmp_path / "scripts" / "hello.py").write_text("print('| a |\\n|---|\\n| 1 |')\n")
    (tmp_path / "tables.yaml").write_text(
        "tables:\n"
        "- {name: quick, title: Quick, script: hello.py}\n"
        "- {name: machine, title: Machine, script: hello.py, on_demand: true}\n"
    )
    tables = rp.read_tables(tmp_path / "tables.yaml", "speed")
    assert [t.on_demand for t in tables] == [False, True]
    monkeypatch.setattr(cli, "declared_tables", lambda root: list(tables))
    monkeypatch.setattr(rp, "commit", lambda root: "c0ffee")
    results = tmp_path / "results"
    argv = ["--results", str(results), "--work", str(tmp_path / "work"), "--root", str(tmp_path)]
    assert cli.main(argv) == 0
    assert "speed.machine" in capsys.readouterr().err  # named as not run
    assert set(json.loads((results / "results.json").read_text())["tables"]) == {"speed.quick"}
    assert cli.main([*argv, "--only", "speed.machine"]) == 0
    assert set(json.loads((results / "results.json").read_text())["tables"]) == {"speed.quick", "speed.machine"}
    assert cli.main(argv) == 0  # the default run again: the on-demand table's result stays in the record
    assert set(json.loads((results / "results.json").read_text())["tables"]) == {"speed.quick", "speed.machine"}


def test_an_on_demand_tables_block_without_a_record_says_how_to_fill_it():
    table = rp.Table("speed.machine", "Machine", "hello.py", (), on_demand=True)
    page = "<!-- results: speed.machine -->\n<!-- /results -->\n"
    filled = rp.fill_page(page, {"tables": {}}, {table.name: table})
    assert "reproduce.py --only speed.machine" in filled and rp.block_names(filled) == ["speed.machine"]
    with pytest.raises(rp.ExcerptError, match="no complete run"):  # any other table must be in the record
        rp.fill_page(page, {"tables": {}}, {table.name: dataclasses.replace(table, on_demand=False)})
