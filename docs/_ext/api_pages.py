"""Sphinx extension: the API reference of the bench's rclpy-free modules, one page per package.

At ``builder-inited`` it writes ``api/generated/PACKAGE.rst`` (reStructuredText, the language of the docstrings)
for every package of ``api_packages`` (found under
``api_source/PACKAGE/PACKAGE``): an ``automodule`` per module, in name order. Left out: the commands
(``*.cli.*``, documented by their ``--help`` and the commands reference) and every module that imports a ROS
client library or a cross-check's test-only library at its top level, directly or through another module of the
bench (the node shells, the Stone Soup and tetra3rs cross-checks): the reference is of the functional core. A page is
rewritten only when its text changes.

The bench's docstrings are plain text with reStructuredText's inline literals and roles. Before autodoc parses
one, ``plain_layout`` makes its layout valid reStructuredText without changing its words: ``|x|`` (an absolute
value, not a substitution) and a stray ``*`` escaped, and a blank line where a list starts under a paragraph or
ends above one, where an indented continuation starts or where one ends. So a docstring written for ``help()`` renders
without warnings.
"""

from __future__ import annotations

import ast
import re
import sys
import unicodedata
from pathlib import Path

from sphinx import addnodes

LEFT_OUT = ("rclpy", "stonesoup", "tetra3rs")
"""Top-level imports that leave a module out: the ROS client library (the node shells) and the independent
libraries the cross-checks compare the bench with (test dependencies, not the bench's API)."""


def modules(source: Path, package: str) -> dict[str, Path]:
    """Every module of a package (dotted name -> file), the package itself included, commands excluded."""
    top = source / package / package
    found = {}
    for path in sorted(top.rglob("*.py")):
        parts = path.relative_to(top.parent).with_suffix("").parts
        if "cli" in parts or "__pycache__" in parts:
            continue
        found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return found


def top_level_imports(path: Path) -> set[str]:
    """The modules a file imports in its module body (not inside functions), as dotted names."""
    names: set[str] = set()
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            names.add(node.module)
            names.update(f"{node.module}.{alias.name}" for alias in node.names)
    return names


def shell_modules(files: dict[str, Path]) -> set[str]:
    """The modules that import one of LEFT_OUT at their top level, directly or through one another (a fixed
    point)."""
    imports = {name: top_level_imports(path) for name, path in files.items()}
    shell = {n for n, used in imports.items() if any(u == r or u.startswith(r + ".") for u in used for r in LEFT_OUT)}
    while True:
        more = {n for n, used in imports.items() if n not in shell and used & shell}
        if not more:
            return shell
        shell |= more


def page(package: str, names: list[str]) -> str:
    """A package's API page (reStructuredText): a title, then an automodule per module."""
    title = f"``{package}``"
    lines = [
        title,
        "=" * len(title),
        "",
        f"The modules of ``{package}`` but its node shells, cross-checks and commands.",
        "",
    ]
    for name in names:
        lines += [f"``{name}``", "-" * (len(name) + 4), "", f".. automodule:: {name}", ""]
    return "\n".join(lines)


def write_pages(app) -> None:
    """builder-inited: write the packages' pages under api/generated/ (only where their text changed)."""
    source, out = Path(app.config.api_source), Path(app.srcdir) / "api" / "generated"
    files = {n: p for package in app.config.api_packages for n, p in modules(source, package).items()}
    shell = shell_modules(files)
    out.mkdir(parents=True, exist_ok=True)
    for package in app.config.api_packages:
        names = sorted(n for n in files if (n == package or n.startswith(package + ".")) and n not in shell)
        target, text = out / f"{package}.rst", page(package, names)
        if not target.is_file() or target.read_text(encoding="utf-8") != text:
            target.write_text(text, encoding="utf-8")


LITERAL = re.compile(r"(``.+?``|:[a-z:]+:`[^`]+`|`[^`]+`_?)")
"""Inline literals, roles and interpreted text, left as they are."""
EMPHASIS = re.compile(r"(\*\*?)(?=\S)[^*]+?(?<=\S)\1(?![\w*])")
"""``*emphasis*`` and ``**strong**``; any other ``*`` (``*u.shape``, ``x * y``) is a character."""
BULLET = re.compile(r"^\s*([-*+]|\d+[.)]|\(\d+\)) ")
FOLLOWS_MARKUP = " \t-.,:;!?\\/'\")]}>"
"""What may follow an inline literal's closing backquotes (besides Unicode punctuation)."""


def escape_text(text: str) -> str:
    """Plain text outside inline markup: ``|`` and stray ``*`` escaped."""
    text = text.replace("|", "\\|")
    kept = [m.span() for m in EMPHASIS.finditer(text)]
    return "".join("\\*" if c == "*" and not any(a <= i < b for a, b in kept) else c for i, c in enumerate(text))


def escape_line(line: str) -> str:
    """A line with its plain text escaped (escape_text) and a literal directly followed by a letter, digit or
    superscript (````Time````s, ````sigma````²) separated from it by an escaped space, which renders as nothing."""
    parts = LITERAL.split(line)
    out = []
    for i, part in enumerate(parts):
        if i % 2 == 0:
            out.append(escape_text(part))
            continue
        out.append(part)
        after = parts[i + 1][:1] if i + 1 < len(parts) else ""
        if after and after not in FOLLOWS_MARKUP and not unicodedata.category(after).startswith("P"):
            out.append("\\ ")
    return "".join(out)


def indent(line: str) -> int:
    return len(line) - len(line.lstrip())


def plain_layout(lines: list[str]) -> list[str]:
    """A docstring's lines as valid reStructuredText (see the module): plain text escaped (escape_line); a blank
    line before a list item or an indented line that follows a non-blank line, before a line that returns to a
    smaller indent, and after a list that a paragraph follows. Literal blocks (after a line ending in ``::``)
    are left alone."""
    out: list[str] = []
    literal_at, list_at = None, None
    for line in lines:
        blank = not line.strip()
        if literal_at is not None and (blank or indent(line) > literal_at):
            out.append(line)
            continue
        literal_at = None
        if blank:
            list_at = None
        previous = out[-1] if out else ""
        if not blank and previous.strip():
            deeper, shallower = indent(line) > indent(previous), indent(line) < indent(previous)
            continues_item = deeper and BULLET.match(previous) and not BULLET.match(line)
            ends_list = list_at is not None and not BULLET.match(line) and indent(line) <= list_at
            if (deeper and not continues_item) or shallower or ends_list or (BULLET.match(line) and not deeper):
                out.append("")
                list_at = None
        if BULLET.match(line):
            list_at = indent(line)
        line = escape_line(line)
        out.append(line)
        if line.rstrip().endswith("::"):
            literal_at = indent(line)
    return out


def normalise_docstring(app, what, name, obj, options, lines: list[str]) -> None:
    """autodoc-process-docstring: the docstring's layout made valid (plain_layout), in place."""
    lines[:] = plain_layout(lines)


def qualify_references(app, doctree) -> None:
    """doctree-read: a bare class name in a signature (an annotation autodoc could not evaluate, e.g. beside a
    ``TYPE_CHECKING`` import) names what that name is in its module, so it resolves there and not to whichever
    class of the same name the site holds."""
    for node in doctree.findall(addnodes.pending_xref):
        target, module = node.get("reftarget", ""), node.get("py:module")
        if node.get("refdomain") != "py" or not module or "." in target:
            continue
        obj = getattr(sys.modules.get(module), target, None)
        home = getattr(obj, "__module__", None)
        if isinstance(obj, type) and home and home != module:
            node["reftarget"] = f"{home}.{obj.__qualname__}"


def setup(app):
    app.add_config_value("api_packages", [], "env")
    app.add_config_value("api_source", "", "env")
    app.connect("builder-inited", write_pages)
    app.connect("autodoc-process-docstring", normalise_docstring)
    app.connect("doctree-read", qualify_references)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
