"""The settings reference (bench_engine.settings_reference) is generated from the declarations the readers read
(bench_engine.settings): every key a scenario file uses appears in it, including the keys its variants and sweep
grids set, and the defaults it states are the values the readers give a key a scenario leaves out."""

from __future__ import annotations

import dataclasses
import importlib.util
import re
import subprocess
import sys
import types
from pathlib import Path

import pytest

from bench_engine import plugins
from bench_engine.config import ScenarioError, load_scenario, merge
from bench_engine.scenario import EngineKeys, check_top_level, section_readers
from bench_engine.settings import REQUIRED, SectionReader, Settings, coerce, default_of, read, setting
from bench_engine.settings_reference import _yaml_value, entries, markdown

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = [
    *plugins.names("scenarios"),
    str(ROOT / "tests/data/tracker_formation.yaml"),
    str(ROOT / "tests/data/clutter_demo.yaml"),
]
REFERENCE = entries()
FREE = [
    e.path for e in REFERENCE if e.type == "mapping" and not any(f.path.startswith(e.path + ".") for f in REFERENCE)
]
"""Keys whose value is a free mapping (variants, sweeps, a grace pairs option): what lies under them is data."""
DEFAULTS_OF = {
    r.key: r.defaults_of for r in section_readers().values() if isinstance(r, SectionReader) and r.defaults_of
}


def _pattern(path: str) -> re.Pattern:
    return re.compile("^" + re.escape(path).replace(re.escape("<name>"), r"([A-Za-z0-9_]+)") + "$")


PATTERNS = [_pattern(e.path) for e in REFERENCE]


def documented(path: str) -> bool:
    """Whether a key path of a scenario is a key of the reference (or data under a free mapping)."""
    first, _, rest = path.partition(".")
    if first in DEFAULTS_OF and rest:
        path = f"{DEFAULTS_OF[first]}.defaults.{rest}"  # any key of an entry of that section
    return any(p.match(path) for p in PATTERNS) or any(path.startswith(f + ".") for f in FREE)


def key_paths(tree: dict, prefix: str = "") -> list[str]:
    out = []
    for key, value in tree.items():
        path = f"{prefix}{key}"
        out.append(path)
        if isinstance(value, dict):
            out += key_paths(value, path + ".")
    return out


def override_paths(cfg: dict) -> list[str]:
    """The key paths the scenario's variants and sweep grids set (and scale)."""
    paths = [k for v in (cfg.get("variants") or {}).values() for k in v]
    for grid in (cfg.get("sweeps") or {}).values():
        paths += list(grid.get("set") or {})
        for axis in grid["axes"].values():
            if "values" in axis:
                paths += list(axis.get("set") or []) + list(axis.get("scale") or [])
            else:
                paths += [k for level in axis.values() if isinstance(level, dict) for k in level.get("set") or {}]
    return paths


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_every_key_a_scenario_uses_is_in_the_reference(scenario: str) -> None:
    cfg = load_scenario(scenario)
    used = key_paths(cfg) + override_paths(cfg)
    missing = [p for p in used if not documented(p)]
    assert not missing, f"keys {scenario} uses that the settings reference lacks: {missing}"


def test_the_matcher_finds_what_it_should() -> None:
    assert documented("sensors.radar.station.lat_deg") and documented("filters.ukf.params.alpha")
    assert documented("filter_defaults.dynamics.sigma_accel") and documented("variants.x.anything")
    assert not documented("sensors.radar.station.latitude") and not documented("filters.ukf.params.gamma")


def _raw(cfg: dict, path: str) -> dict:
    """The mapping of the scenario at a key path as its reader reads it (an entry merged over its defaults)."""
    section, name, *rest = path.split(".") + [""]
    inverse = {v: k for k, v in DEFAULTS_OF.items()}
    node = cfg.get(section) or {}
    if section in inverse and name:
        node = merge(cfg.get(inverse[section]) or {}, node.get(name) or {})
        node.setdefault("type", name)
        rest = [r for r in rest if r]
    else:
        rest = [r for r in [name, *rest] if r]
    for part in rest:
        node = node.get(part) or {}
    return node


def _instances(obj, found: list) -> None:
    if isinstance(obj, Settings):
        found.append(obj)
        for f in dataclasses.fields(obj):
            _instances(getattr(obj, f.name), found)
    elif isinstance(obj, dict):
        for value in obj.values():
            _instances(value, found)


def _entries_of(cfg: dict, path: str) -> list:
    """The reference entries of a concrete key path that apply to the scenario (their ``when`` holds)."""
    out = []
    for e, pattern in zip(REFERENCE, PATTERNS):
        match = pattern.match(path)
        if match is None:
            continue
        names = iter(match.groups())
        clauses = [c.split(" = ") for c in e.when.split(", ")] if e.when else []
        concrete = [(re.sub("<name>", lambda _, names=names: next(names, "<name>"), k), v) for k, v in clauses]
        if all(str(_raw(cfg, k.rsplit(".", 1)[0]).get(k.rsplit(".", 1)[1])) == v for k, v in concrete):
            out.append(e)
    return out


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_the_reference_defaults_are_the_readers_defaults(scenario: str) -> None:
    """Read by the registered readers, every key the scenario leaves out has the value the reference states."""
    cfg = load_scenario(scenario)
    found: list = []
    _instances(check_top_level(cfg), found)
    for key, reader in section_readers().items():
        if key in cfg and isinstance(reader, SectionReader) and not reader.defaults_of:
            _instances(reader(cfg), found)
    checked = 0
    for obj in found:
        raw = _raw(cfg, obj.where()) if obj.where() else cfg
        for f in dataclasses.fields(obj):
            if f.name in raw or "variant" in f.metadata or f.metadata.get("default_text"):
                continue
            entry = _entries_of(cfg, obj.where(f.name))
            assert len(entry) == 1, (obj.where(f.name), entry)
            assert entry[0].default == _yaml_value(getattr(obj, f.name)), obj.where(f.name)
            checked += 1
    assert checked > 10


def test_the_reference_lists_every_declared_key_once_with_type_default_unit_and_meaning() -> None:
    text = markdown()
    assert all(e.doc for e in REFERENCE), [e.path for e in REFERENCE if not e.doc]
    assert len({(e.path, e.when) for e in REFERENCE}) == len(REFERENCE)
    for e in REFERENCE:
        assert f"`{e.path}`" in text
    assert "| `earth.mu` | number | `3.986004418e+14` | m^3/s^2 | > 0 | gravitational parameter GM |" in text
    assert "When `sensors.<name>.type = ground_radar`:" in text
    for key in ("estimators", "filters", "trackers", "star_trackers", "fixed_lag_smoothers"):
        assert f"## `{key}`" in text


def test_the_command_writes_the_reference(tmp_path: Path) -> None:
    out = tmp_path / "settings.md"
    res = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "settings_reference.py"), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 0, res.stderr
    assert out.read_text() == markdown()
    res = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "settings_reference.py"), "--help"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 0 and "--out" in res.stdout


def test_the_docs_site_writes_the_reference_page_when_it_is_built(tmp_path: Path) -> None:
    """docs/_ext/settings_page.py writes reference/settings.md from markdown() at builder-inited (`make docs`)."""
    spec = importlib.util.spec_from_file_location("docs_ext_settings_page", ROOT / "docs/_ext/settings_page.py")
    extension = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(extension)
    (tmp_path / "reference").mkdir()
    extension.write_page(types.SimpleNamespace(srcdir=str(tmp_path)))
    assert (tmp_path / "reference" / "settings.md").read_text(encoding="utf-8") == markdown()
    assert "reference/settings" in (ROOT / "docs/index.md").read_text()


@dataclasses.dataclass(frozen=True, kw_only=True)
class _Example(Settings):
    dt: float = setting(unit="s", doc="a period")
    n: int = setting(3, doc="a count")
    names: list[str] | None = setting(None, doc="names", old=("labels",))


def test_a_reader_is_strict_and_its_errors_name_the_key_path() -> None:
    assert read(_Example, {"dt": 1, "n": 2}, "x") == _Example(dt=1.0, n=2)
    assert isinstance(read(_Example, {"dt": "1e-3"}, "x").dt, float)  # YAML 1.1 reads 1e-3 as text
    for data, message in (
        ({}, "missing key 'x.dt'"),
        ({"dt": 1, "m": 2}, "unknown key(s) 'x.m' in 'x'; allowed:"),
        ({"dt": "a"}, "'x.dt' must be a number, got 'a'"),
        ({"dt": 1, "n": 1.5}, "'x.n' must be an integer"),
        ({"dt": 1, "names": [1]}, "'x.names' must be a list of strings"),
    ):
        with pytest.raises(ScenarioError, match=re.escape(message)):
            read(_Example, data, "x")
    example = read(_Example, {"dt": 1}, "x.y")
    assert (example.where(), example.where("dt")) == ("x.y", "x.y.dt")  # a path for the mapping and for its keys
    assert coerce(_Example, {"dt": 2, "labels": ["a"], "other": 1}) == {"dt": 2.0, "names": ["a"], "other": 1}
    assert default_of(dataclasses.fields(_Example)[0]) is REQUIRED
    with pytest.raises(ScenarioError, match="unknown key\\(s\\) 'earth.muu' in 'earth'; allowed: j2, mu, re,"):
        section_readers()["earth"]({"earth": {"muu": 1.0}})


def test_the_engine_declares_its_own_keys() -> None:
    assert [f.name for f in dataclasses.fields(EngineKeys)] == [
        "scenario",
        "description",
        "seed",
        "time",
        "estimators",
        "standard_views",
        "variants",
        "sweeps",
    ]
