"""The repository stands on its own and its door stays a page: no tracked file points at a folder outside the
repository or cites a paper by a file name only a local copy has; the README fits on a page; the docs build's
step runner appends its shortening where a reader's command would take it. (The site itself is built, with
warnings as errors, by `make docs` in CI.)"""

import importlib.util
import re
import subprocess

import pytest
from graph_helpers import ROOT


def docs_extension(name: str):
    """One of the docs build's local extensions (docs/_ext/NAME.py), loaded from its file."""
    spec = importlib.util.spec_from_file_location(f"docs_ext_{name}", ROOT / "docs" / "_ext" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


OUTSIDE = re.compile("|".join([re.escape(".." + "/shared"), "SCENARIOS" + r"\.md", "ROS_ON_PIP" + r"\.md"]))
"""A reference shelf beside the repository that no other clone has."""
FILE_CITATION = re.compile(r"\b00[0-4]_[0-9a-f]{16}\b")
"""A paper cited by the name of a local file (cite it by its authors and title: docs/studies/index.md)."""


def tracked_text_files() -> list:
    names = subprocess.run(
        ["git", "-C", str(ROOT), "ls-files", "-z"], capture_output=True, text=True, check=True
    ).stdout.split("\0")
    files = []
    for name in filter(None, names):
        path = ROOT / name
        if path.is_file() and path.suffix not in (".png", ".mcap", ".db3"):
            try:
                files.append((name, path.read_text(encoding="utf-8")))
            except UnicodeDecodeError:
                continue
    return files


def test_no_tracked_file_points_outside_the_repository_or_cites_a_paper_by_its_file_name():
    offending = [
        f"{name}:{text[: m.start()].count(chr(10)) + 1}: {m.group(0)}"
        for name, text in tracked_text_files()
        for pattern in (OUTSIDE, FILE_CITATION)
        for m in pattern.finditer(text)
    ]
    assert offending == []


def test_the_patterns_catch_what_they_are_for():
    assert OUTSIDE.search("see " + ".." + "/shared/" + "SCENARIOS" + ".md") and not OUTSIDE.search("--out /shared/mc")
    assert FILE_CITATION.search("Paper 002_" + "2f5c41c22f687bff") and not FILE_CITATION.search("paper 002, eq. 27")


def test_the_readme_fits_on_a_page():
    assert len((ROOT / "README.md").read_text(encoding="utf-8").splitlines()) <= 200


@pytest.mark.parametrize(
    "text, expected",
    [
        (
            ".venv/bin/python scripts/launch.py leo_radar --out runs/a",
            ".venv/bin/python scripts/launch.py leo_radar --out runs/a --runs 1",
        ),
        (
            ".venv/bin/python scripts/launch.py leo_radar \\\n    --out runs/a  # one pass",
            ".venv/bin/python scripts/launch.py leo_radar      --out runs/a --runs 1 # one pass",
        ),
        (
            "export X=1\n.venv/bin/python scripts/score.py a | tail -3",
            "export X=1\n.venv/bin/python scripts/score.py a --runs 1 | tail -3",
        ),
        ("mkdir -p runs", "mkdir -p runs"),
    ],
)
def test_the_docs_step_runner_shortens_only_bench_commands_at_their_end(text, expected):
    assert docs_extension("run_blocks").shortened(text, "--runs 1") == expected


def test_the_api_pages_make_a_plain_docstring_valid_restructuredtext_without_changing_its_words():
    api = docs_extension("api_pages")
    lines = [
        "Returns |x| for:",
        "- a list item",
        "  continued",
        "text after the list",
        "    an indented line",
        "three ``Time``s",
        "::",
        "",
        "    |literal| kept",
    ]
    assert api.plain_layout(lines) == [
        "Returns \\|x\\| for:",
        "",
        "- a list item",
        "  continued",
        "",
        "text after the list",
        "",
        "    an indented line",
        "",
        "three ``Time``\\ s",
        "::",
        "",
        "    |literal| kept",
    ]
