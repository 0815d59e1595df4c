"""The bench's packages depend one way, in LAYERS order: a package imports, names in a module string
("pkg.module" or "pkg.module:attr") or registers as an entry point only itself and the packages below it.
Scripts import no other script, and nothing puts scripts/ on sys.path.

A layering violation is found three ways: statically (every import statement, function-level ones included,
and every string that names a bench module), through the entry points each setup.py registers, and at run
time (importing a package's modules loads no package above it).
"""
from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "ros_ws" / "src"
LAYERS = ("bench_engine", "orbit_sim", "bench_models", "radar_sensor", "tracker_filters", "star_tracker",
          "bench_eval", "bench_studies")
"""Lowest first. bench_msgs (generated messages) is below all of them."""
PRESENT = [p for p in LAYERS if (SRC / p / p).is_dir()]
MODULE_STRING = re.compile(rf"^({'|'.join(LAYERS)})(\.[A-Za-z_]\w*)*(:[A-Za-z_]\w*)?$")


def rank(package: str) -> int:
    return LAYERS.index(package)


def references(path: Path) -> list[tuple[int, str]]:
    """(line, bench package) of every import and every module string in a Python file."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module]
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and MODULE_STRING.match(node.value):
            names = [node.value]
        found += [(node.lineno, n.split(".")[0].split(":")[0]) for n in names if n.split(".")[0].split(":")[0] in LAYERS]
    return found


def test_the_layers_list_every_package_of_the_workspace():
    packages = {p.name for p in SRC.iterdir() if (p / "setup.py").is_file()}
    assert packages == set(PRESENT), "add a new package to LAYERS at its place in the dependency order"


@pytest.mark.parametrize("package", PRESENT)
def test_a_package_references_nothing_above_it(package):
    upward = [f"{path.relative_to(ROOT)}:{line} -> {other}"
              for path in sorted((SRC / package).rglob("*.py"))
              for line, other in references(path) if rank(other) > rank(package)]
    assert not upward, f"{package} reaches packages above it:\n" + "\n".join(upward)


@pytest.mark.parametrize("package", PRESENT)
def test_package_xml_declares_every_bench_package_it_uses(package):
    used = {other for path in (SRC / package / package).rglob("*.py") for _, other in references(path)} - {package}
    declared = set(re.findall(r"<exec_depend>(\w+)</exec_depend>", (SRC / package / "package.xml").read_text()))
    below = {p for p in declared if p in LAYERS}
    assert used <= declared, f"{package}/package.xml lacks exec_depend on {sorted(used - declared)}"
    assert all(rank(p) < rank(package) for p in below)


def test_the_static_check_catches_an_upward_module_string(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text('import numpy\nNODE = "bench_eval.report:render"\nfrom tracker_filters import kf\n')
    assert sorted(references(bad)) == [(2, "bench_eval"), (3, "tracker_filters")]


@pytest.mark.parametrize("package", PRESENT)
def test_entry_points_register_only_the_packages_own_components(package):
    setup = (SRC / package / "setup.py").read_text()
    targets = re.findall(r'"[^"=]+=\s*([\w.]+):[\w.]+"', setup)
    assert all(t.split(".")[0] == package for t in targets), targets


@pytest.mark.parametrize("package", [p for p in PRESENT if p != LAYERS[-1]])
def test_importing_a_package_loads_nothing_above_it(package):
    modules = sorted(f"{package}.{p.stem}" for p in (SRC / package / package).glob("*.py")
                     if p.stem != "__init__" and not p.stem.endswith("_node"))
    code = ("import sys\n" + "".join(f"import {m}\n" for m in modules)
            + "print(' '.join(sorted({m.split('.')[0] for m in sys.modules})))")
    loaded = set(subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                                text=True).stdout.split())
    above = loaded & set(LAYERS[rank(package) + 1:])
    assert package in loaded and not above, f"{package} loads {above}"


def test_scripts_import_no_other_script_and_nothing_edits_sys_path():
    scripts = {p.stem for p in (ROOT / "scripts").glob("*.py")}
    offenders = []
    for path in sorted((ROOT / "scripts").glob("*.py")) + sorted((ROOT / "tests").glob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Import) and any(a.name in scripts for a in node.names) \
                    or isinstance(node, ast.ImportFrom) and node.module in scripts:
                offenders.append(f"{path.relative_to(ROOT)}:{node.lineno} imports a script")
            if isinstance(node, ast.Attribute) and node.attr == "path" and isinstance(node.value, ast.Name) \
                    and node.value.id == "sys":
                offenders.append(f"{path.relative_to(ROOT)}:{node.lineno} uses sys.path")
    assert not offenders, "\n".join(offenders)
