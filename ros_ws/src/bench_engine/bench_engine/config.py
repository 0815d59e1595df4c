"""Scenario files: loading, command-line overrides and strict, self-describing validation.

A scenario is a YAML mapping, registered by its study (entry-point group ``tracking_bench.scenarios``).
Overrides ``key.path=value`` are applied on top (the value is parsed as YAML). :class:`Section` reads one
mapping strictly: it records the keys asked for, and :meth:`Section.finish` rejects any key nobody asked for,
naming it and the allowed keys; checks on values raise :class:`ScenarioError` naming the full key path. The
scenario's sections are declared and read through it by bench_engine.settings (typed, once); other files of
the bench (a study's paper.yaml and tables.yaml, a sweep grid) use it directly.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

import yaml

from bench_engine import plugins, yamlio
from bench_engine.errors import ScenarioError  # defined below plugins, which raises it too; imported from here


def _registered_scenarios() -> dict[str, Path]:
    """Scenario files registered by the studies (entry-point group ``tracking_bench.scenarios``)."""
    return {name: Path(str(plugins.load("scenarios", name))) for name in plugins.names("scenarios")}


def available_scenarios() -> list[str]:
    """Names of the registered scenarios."""
    return sorted(_registered_scenarios())


def scenario_path(name_or_path: str) -> Path:
    """Resolve a registered scenario's name or a path to a YAML file."""
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") and path.is_file():
        return path
    registered = _registered_scenarios()
    if name_or_path in registered:
        return registered[name_or_path]
    raise ScenarioError(
        f"unknown scenario '{name_or_path}'; available: {', '.join(sorted(registered))} "
        "(or give the path of a scenario YAML file)"
    )


def parse_override(text: str) -> tuple[list[str], Any]:
    """Split ``a.b.c=value`` into its key path and YAML-parsed value."""
    if "=" not in text:
        raise ScenarioError(f"override {text!r} must look like key.path=value")
    key, raw = text.split("=", 1)
    path = [p for p in key.strip().split(".") if p]
    if not path:
        raise ScenarioError(f"override {text!r} has an empty key")
    try:
        value = yamlio.load(raw)
    except yaml.YAMLError as err:
        raise ScenarioError(f"override {text!r}: value is not valid YAML ({' '.join(str(err).split())})") from err
    return path, value


def apply_overrides(cfg: dict, overrides: Iterable[str]) -> dict:
    """Return a copy of cfg with each ``key.path=value`` override applied (creating missing mappings)."""
    cfg = copy.deepcopy(cfg)
    for text in overrides:
        path, value = parse_override(text)
        node = cfg
        for depth, key in enumerate(path[:-1]):
            child = node.get(key)
            if child is None:
                child = node[key] = {}
            if not isinstance(child, dict):
                where = ".".join(path[: depth + 1])
                raise ScenarioError(f"override {text!r}: '{where}' is a value, not a section")
            node = child
        node[path[-1]] = value
    return cfg


def lookup(data: Mapping, path: str | None) -> Any:
    """The value at a dotted key path (``a.b.c``, as overrides name it) of nested mappings; None when the path is
    None or absent."""
    if path is None:
        return None
    node: Any = data
    for part in path.split("."):
        if not isinstance(node, Mapping) or part not in node:
            return None
        node = node[part]
    return node


def load_scenario(name_or_path: str, overrides: Iterable[str] = ()) -> dict:
    """Read a scenario file and apply overrides; returns the raw mapping (validate with the builders)."""
    path = scenario_path(name_or_path)
    with open(path, encoding="utf-8") as f:
        try:
            cfg = yamlio.load(f) or {}
        except yaml.YAMLError as err:
            mark = getattr(err, "problem_mark", None)
            where = f", line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
            what = " ".join(str(getattr(err, "problem", None) or "a syntax error").split())
            raise ScenarioError(f"{path}{where}: not valid YAML ({what}): fix the file's syntax") from err
    if not isinstance(cfg, dict):
        raise ScenarioError(f"{path}: a scenario must be a YAML mapping")
    cfg = apply_overrides(cfg, overrides)
    cfg.setdefault("scenario", path.stem)
    return cfg


def override_strings(mapping: dict) -> list[str]:
    """{key.path: value} -> ["key.path=value", ...] (values as flow-style YAML)."""
    return [
        f"{k}={yamlio.dump(v, default_flow_style=True, width=10**6).strip().removesuffix(chr(10) + '...')}"
        for k, v in mapping.items()
    ]


def merge(base: dict, extra: dict) -> dict:
    """``base`` updated by ``extra``, nested mappings merged key by key."""
    out = dict(base)
    for key, value in extra.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = merge(out[key], value)
        else:
            out[key] = value
    return out


def select_variant(cfg: dict, variant: str | None) -> dict:
    """Apply the named entries (comma-separated, in order) of the scenario's ``variants`` section, each a
    mapping of key.path: value."""
    variants = cfg.get("variants") or {}
    for name in [v.strip() for v in (variant or "").split(",") if v.strip()]:
        if name not in variants:
            raise ScenarioError(f"unknown variant '{name}'; allowed: {', '.join(sorted(variants)) or 'none'}")
        cfg = apply_overrides(cfg, override_strings(variants[name]))
    return cfg


class Section:
    """Typed, checked access to one mapping of the scenario; remembers which keys were read."""

    def __init__(self, data: Any, path: str) -> None:
        if data is None:
            data = {}
        if not isinstance(data, dict):
            raise ScenarioError(f"'{path}' must be a mapping of keys, got {type(data).__name__}")
        self.data = data
        self.path = path
        self._known: set[str] = set()

    def _key(self, key: str) -> str:
        return f"{self.path}.{key}" if self.path else key

    def get(
        self,
        key: str,
        kind: type | tuple[type, ...],
        default: Any = ...,
        check: Callable[[Any], bool] | None = None,
        expect: str = "",
    ) -> Any:
        """Value of ``key`` converted to ``kind``; ``check`` failing raises naming ``expect``."""
        self._known.add(key)
        if key not in self.data or self.data[key] is None:
            if default is ...:
                raise ScenarioError(f"missing key '{self._key(key)}'")
            return default
        value = self.data[key]
        value = _coerce(value, kind, self._key(key))
        if check is not None and not check(value):
            raise ScenarioError(f"'{self._key(key)}' must be {expect}, got {value!r}")
        return value

    def positive(self, key: str, default: Any = ...) -> float:
        return self.get(key, float, default, lambda v: v > 0, "> 0")

    def choice(self, key: str, allowed: Iterable[str], default: Any = ...) -> str:
        allowed = list(allowed)
        return self.get(key, str, default, lambda v: v in allowed, f"one of {allowed}")

    def section(self, key: str, default_empty: bool = True) -> Section:
        self._known.add(key)
        if key not in self.data and not default_empty:
            raise ScenarioError(f"missing section '{self._key(key)}'")
        return Section(self.data.get(key), self._key(key))

    def keys(self) -> list[str]:
        return list(self.data)

    def mark(self, *keys: str) -> None:
        """Declare keys as known without reading them (e.g. comments-only documentation keys)."""
        self._known.update(keys)

    def finish(self) -> None:
        """Raise if the mapping holds keys nobody read."""
        unknown = sorted(set(self.data) - self._known)
        if unknown:
            where = f"'{self.path}'" if self.path else "the scenario's top level"
            raise ScenarioError(
                f"unknown key(s) {', '.join(repr(self._key(k)) for k in unknown)} in {where}; "
                f"allowed: {', '.join(sorted(self._known))}"
            )


def _coerce(value: Any, kind: type | tuple[type, ...], key: str) -> Any:
    kinds = kind if isinstance(kind, tuple) else (kind,)
    if bool in kinds and isinstance(value, bool):
        return value
    if isinstance(value, bool) and bool not in kinds:
        raise ScenarioError(f"'{key}' must be {_names(kinds)}, got a boolean {value!r}")
    if float in kinds and isinstance(value, (int, float)):
        return float(value)
    if float in kinds and isinstance(value, str):
        try:  # PyYAML (YAML 1.1) reads "1e-3" (no dot) as a string
            return float(value)
        except ValueError:
            pass
    if int in kinds and isinstance(value, int):
        return value
    if isinstance(value, kinds):
        return value
    raise ScenarioError(f"'{key}' must be {_names(kinds)}, got {value!r}")


def _names(kinds: tuple[type, ...]) -> str:
    return " or ".join(
        {
            float: "a number",
            int: "an integer",
            str: "a string",
            bool: "true/false",
            list: "a list",
            dict: "a mapping",
        }.get(k, k.__name__)
        for k in kinds
    )
