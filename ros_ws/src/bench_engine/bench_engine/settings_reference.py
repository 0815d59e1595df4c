"""The settings reference: every scenario key with its type, default, unit and meaning, generated from the very
declarations the readers read (bench_engine.settings), so the documentation and the validation cannot disagree.

    python -m bench_engine.settings_reference [--out FILE]      (or scripts/settings_reference.py)

The keys are the engine's own (bench_engine.scenario.EngineKeys) and those of every section registered under
``tracking_bench.sections`` (a bench_engine.settings.SectionReader each): the installed packages' sections,
plugins' included. ``<name>`` stands for a name the scenario chooses (a sensor's, an estimator's).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from itertools import groupby
from pathlib import Path
from typing import Any

from bench_engine.scenario import EngineKeys, section_readers
from bench_engine.settings import REQUIRED, SectionReader, Shape, choices_of, default_of, fields_of, join, shape

INTRO = """\
# Scenario settings

Every key a scenario file may hold, generated from the code that reads it (`bench_engine.settings_reference`).
A key not listed here stops the launcher with a message naming it; `--set KEY.PATH=VALUE` overrides any of them,
and a node's ROS parameters carry the same names (`ros2 param get /ukf earth.mu`). `<name>` stands for a name
the scenario chooses. Units are SI unless the key's name or unit says otherwise.

Words: an *estimator* is any node that publishes estimates (`/NAME/estimate`): a filter, a tracker, a
fixed-lag smoother, a star tracker. The top-level key `estimators` (and the command line's `--estimators`)
selects the estimators a run starts, of any kind. The section `filters` configures the estimators of the
filter kind only, as `trackers`, `star_trackers` and `fixed_lag_smoothers` configure theirs.
"""


def section_entries(reader: SectionReader) -> Iterator[Entry]:
    """A registered section's key and every key it declares (one Entry for a section of defaults of another)."""
    sh = shape(reader.schema)
    yield Entry(reader.key, "mapping of named entries" if sh.entries else "mapping", "{}", "", reader.doc)
    if not reader.defaults_of:
        yield from _nested(sh, reader.key, "")


def entries() -> list[Entry]:
    """Every documented key: the engine's, then each registered section's (by key)."""
    out = list(declared(EngineKeys))
    for key, reader in sorted(section_readers().items()):
        if isinstance(reader, SectionReader):
            out += list(section_entries(reader))
        else:
            out.append(Entry(key, "mapping", "", "", "(this section's reader declares no keys: see its package)"))
    return out


@dataclass(frozen=True)
class Entry:
    """One key of the settings reference: ``path`` (``<name>`` where the scenario names an entry), its type,
    default, unit, meaning, the allowed values, and ``when`` it applies (e.g. ``sensors.<name>.type =
    ground_radar``; empty: always)."""

    path: str
    type: str
    default: str
    unit: str
    doc: str
    allowed: str = ""
    when: str = ""
    computed: bool = False
    """The default is computed when the key is read (``default`` says how), not a value."""


def describe_default(f: dataclasses.Field) -> str:
    """A field's default as the reference shows it."""
    if f.metadata.get("default_text"):
        return f.metadata["default_text"]
    value = default_of(f)
    return "required" if value is REQUIRED else _yaml_value(value)


def _yaml_value(value: Any) -> str:
    """A value as the reference writes it (YAML flow style)."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "inf" if value == float("inf") else format(value, ".12g")
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_yaml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {_yaml_value(v)}" for k, v in value.items()) + "}"
    return str(value)


def declared(cls: type, prefix: str = "", when: str = "") -> Iterator[Entry]:
    """Every key ``cls`` declares, depth first, as reference :class:`Entry`s under key path ``prefix``."""
    for f, hint in fields_of(cls):
        var = f.metadata.get("variant")
        if var is not None:
            base = prefix if var.inline else join(prefix, f.name)
            selector = join(prefix, var.selected_by)
            if not var.inline:
                yield Entry(base, "mapping", "{}", "", f.metadata.get("doc", ""), "", when)
            for name in var.names():
                option = var.load(name)
                condition = f"{selector} = {name}"
                if option is not None:
                    yield from declared(option, base, f"{when}, {condition}" if when else condition)
            continue
        path, sh, meta = join(prefix, f.name), shape(hint), f.metadata
        check, choices = meta.get("check"), choices_of(meta)
        allowed = ", ".join(choices) if choices is not None else (check.text if check else "")
        yield Entry(
            path,
            sh.text(),
            describe_default(f),
            meta.get("unit", ""),
            meta.get("doc", ""),
            allowed,
            when,
            bool(meta.get("default_text")),
        )
        if sh.settings is not None:
            yield from _nested(sh, path, when)


def _nested(sh: Shape, path: str, when: str) -> Iterator[Entry]:
    """The entries of a nested Settings class, or of named entries of it (one for the entry itself)."""
    if sh.entries:
        path = f"{path}.<name>"
        yield Entry(path, "mapping", "required", "", _summary(sh.settings), "", when)
    yield from declared(sh.settings, path, when)


def _summary(cls: type) -> str:
    """The first sentence of a class's docstring."""
    return " ".join((cls.__doc__ or "").split()).split(". ")[0].rstrip(".")


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _code(text: str) -> str:
    return f"`{text}`" if text else ""


def markdown() -> str:
    """The reference as Markdown: one part per top-level key, a table per group of keys (a group: the keys that
    apply when another key has a given value, e.g. a sensor's ``type``)."""
    lines = [INTRO]
    for section, group in groupby(entries(), key=lambda e: e.path.split(".")[0]):
        group = list(group)
        head = next((e for e in group if e.path == section), None)
        lines += [f"## `{section}`", ""]
        rest = [e for e in group if e.path != section]
        if not rest:
            lines += _table(group) + [""]
            continue
        if head is not None and head.doc:
            lines += [head.doc[:1].upper() + head.doc[1:] + ".", ""]
        for when, rows in groupby(rest, key=lambda e: e.when):
            if when:
                lines += [f"When `{when}`:", ""]
            lines += _table(list(rows)) + [""]
    return "\n".join(lines).rstrip() + "\n"


def _table(rows: list[Entry]) -> list[str]:
    out = ["| key | type | default | unit | allowed | meaning |", "|---|---|---|---|---|---|"]
    for e in rows:
        default = e.default if e.computed or e.default in ("required", "") else _code(e.default)
        out.append(
            f"| {_code(e.path)} | {_cell(e.type)} | {_cell(default)} | {_cell(e.unit)} | {_cell(e.allowed)} "
            f"| {_cell(e.doc)} |"
        )
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, help="write the Markdown here (default: print it)")
    args = p.parse_args(argv)
    text = markdown()
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text, encoding="utf-8")
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
