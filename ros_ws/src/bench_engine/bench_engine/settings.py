"""Typed scenario settings: every key declared once, with its type, default, unit, meaning and check.

A section, or one mapping inside it, is a frozen, keyword-only dataclass deriving from :class:`Settings` whose
fields are its keys, each declared with :func:`setting`. The annotation is the key's type: ``bool``, ``int``,
``float``, ``str``, a ``list`` of one of those, a free mapping (``dict``), another Settings class (a nested
mapping), ``dict[str, X]`` with X a Settings class (named entries: ``sensors: {radar: {…}}``), or a union of those
with ``None`` (optional).
:func:`variant` declares the keys that depend on another key's value (a sensor's ``type``, a dynamics ``model``):
the chosen option's Settings class, read beside that key or under a key of its own.

:func:`read` reads a mapping into an instance, strictly (bench_engine.config.Section): a value of the wrong type,
a failed check or a key nobody declared raises ScenarioError in one line naming the full key path and what is
allowed. Numbers are converted to the declared type (an integer for a ``float`` key becomes a float, and so
does the text "3.986004418e14", which YAML 1.1 reads as a string). A class may check its keys together in
``validate(path)``. :func:`coerce` gives a mapping's declared values their types without checking anything (a
node's ROS parameters: bench_engine.parameters), and bench_engine.settings_reference lists every key from the
same declarations, so the reference and the validation cannot disagree.

    @dataclass(frozen=True, kw_only=True)
    class Time(Settings):
        dt: float = setting(unit="s", doc="the lock-step period", check=POSITIVE)
        pacing_window: int = setting(0, doc="steps the source may run ahead", check=NON_NEGATIVE)

No rclpy, nothing heavy: every node kind's module reads its section through this.
"""

from __future__ import annotations

import copy
import dataclasses
import datetime
import sys
import types
import typing
from collections.abc import Callable, Iterable
from dataclasses import MISSING, dataclass, field
from functools import cache
from typing import Any

from bench_engine import plugins
from bench_engine.config import ScenarioError, Section

REQUIRED = MISSING
"""The default of a key that must be given."""


@dataclass(frozen=True)
class Check:
    """A condition on a key's value and how the error states it (``'KEY' must be TEXT, got VALUE``)."""

    test: Callable[[Any], bool]
    text: str


POSITIVE = Check(lambda v: v > 0, "> 0")
NON_NEGATIVE = Check(lambda v: v >= 0, ">= 0")
PROBABILITY = Check(lambda v: 0.0 <= v <= 1.0, "in [0, 1]")


def at_least(low: float, what: str = "an integer") -> Check:
    return Check(lambda v: v >= low, f"{what} >= {low:g}")


def between(low: float, high: float, unit: str = "", what: str = "in") -> Check:
    """low <= value <= high."""
    return Check(lambda v: low <= v <= high, f"{what} [{low:g}, {high:g}]{' ' + unit if unit else ''}")


def setting(
    default: Any = REQUIRED,
    *,
    doc: str,
    unit: str = "",
    check: Check | None = None,
    choices: Iterable[str] | Callable[[], Iterable[str]] | None = None,
    old: tuple[str, ...] = (),
    default_text: str = "",
) -> Any:
    """A scenario key (a dataclass field): ``default`` (REQUIRED: none), ``doc`` its meaning, ``unit`` (SI),
    ``check`` a condition on its value, ``choices`` the allowed values (or a function giving them, e.g. the
    registered names), ``old`` deprecated names still read (with a one-line notice), ``default_text`` what the
    reference says of a default computed elsewhere (e.g. "the sensor's name + '_enu'")."""
    meta = {"doc": doc, "unit": unit, "check": check, "choices": choices, "old": old, "default_text": default_text}
    if isinstance(default, (list, dict)):
        return field(default_factory=lambda: copy.deepcopy(default), metadata=meta)
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class Variant:
    """Keys that depend on another key's value: ``selected_by`` (a key declared before) names an option among
    ``names()``; ``load(name)`` is that option's Settings class. ``inline``: its keys sit beside the selecting
    key; else under the variant field's own key."""

    selected_by: str
    names: Callable[[], Iterable[str]]
    load: Callable[[str], type]
    inline: bool = True


def variant(
    selected_by: str,
    names: Callable[[], Iterable[str]],
    load: Callable[[str], type],
    *,
    inline: bool = True,
    doc: str = "",
) -> Any:
    """A field holding the Settings of the option ``selected_by`` names (:class:`Variant`)."""
    return field(default=None, metadata={"variant": Variant(selected_by, names, load, inline), "doc": doc})


class Settings:
    """Base of the typed settings classes (frozen dataclasses of :func:`setting` fields). An instance read by
    :func:`read` knows where it was read: :meth:`where` names its keys in error messages."""

    _path = ""

    def validate(self, path: str) -> None:
        """Checks across keys (ScenarioError naming them); the default has none."""

    def where(self, key: str = "") -> str:
        """The full key path of ``key`` of this mapping (of the mapping itself without one)."""
        return join(self._path, key) if key else self._path


@dataclass(frozen=True, kw_only=True)
class NoKeys(Settings):
    """The settings of a choice that has no keys of its own (an offline estimator without parameters)."""


@dataclass(frozen=True)
class Builder:
    """A registered component configured by one Settings class: ``settings`` (the keys it reads; cheap to import,
    the graph and the settings reference read it) and ``build``, the ``module:function`` that builds it from
    them, imported when something is built. Calling the Builder calls that function."""

    settings: type
    build: str

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return plugins.resolve(self.build)(*args, **kwargs)


def replaced(obj: Settings, **changes: Any) -> Any:
    """``dataclasses.replace`` that keeps where ``obj`` was read (:meth:`Settings.where`)."""
    new = dataclasses.replace(obj, **changes)
    object.__setattr__(new, "_path", obj._path)
    return new


# --- types ------------------------------------------------------------------------------------------------

SCALARS = (bool, int, float, str, datetime.datetime)
TYPE_TEXT = {
    bool: "true/false",
    int: "integer",
    float: "number",
    str: "string",
    dict: "mapping",
    object: "any",
    datetime.datetime: "date and time",
}


@dataclass(frozen=True)
class Shape:
    """What an annotation allows: ``kinds`` for Section.get, a list's ``item`` type, a nested Settings class
    (``entries``: a mapping of named entries of that class), ``optional`` (None allowed)."""

    kinds: tuple[type, ...]
    item: type | None = None
    settings: type | None = None
    entries: bool = False
    optional: bool = False

    def text(self) -> str:
        parts = []
        for kind in self.kinds:
            if kind is list:
                parts.append(f"list of {TYPE_TEXT[self.item]}s" if self.item else "list")
            elif kind is dict and self.entries:
                parts.append("mapping of named entries")
            else:
                parts.append(TYPE_TEXT.get(kind, kind.__name__))
        return " or ".join(parts) + (" or null" if self.optional else "")


def shape(hint: Any) -> Shape:
    """The :class:`Shape` of a resolved annotation (TypeError for one this module cannot read)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        parts = [shape(a) for a in args if a is not type(None)]
        nested = next((p for p in parts if p.settings), None)
        return Shape(
            tuple(k for p in parts for k in p.kinds),
            next((p.item for p in parts if p.item), None),
            nested.settings if nested else None,
            bool(nested and nested.entries),
            optional=type(None) in args,
        )
    if hint is list or origin is list:
        return Shape((list,), args[0] if args and args[0] in SCALARS else None)
    if hint is dict or origin is dict:
        if len(args) == 2 and _is_settings(args[1]):
            return Shape((dict,), settings=args[1], entries=True)
        return Shape((dict,))
    if _is_settings(hint):
        return Shape((dict,), settings=hint)
    if hint in SCALARS:
        return Shape((hint,))
    if hint is Any:
        return Shape((object,))
    raise TypeError(f"a setting cannot be of type {hint!r}")


def _is_settings(hint: Any) -> bool:
    return isinstance(hint, type) and issubclass(hint, Settings)


@cache
def fields_of(cls: type) -> tuple[tuple[dataclasses.Field, Any], ...]:
    """(field, resolved annotation) of a Settings class, in declaration order."""
    hints = typing.get_type_hints(cls)
    return tuple((f, hints[f.name]) for f in dataclasses.fields(cls))


def default_of(f: dataclasses.Field) -> Any:
    """A field's default (REQUIRED if it has none)."""
    if f.default is not MISSING:
        return f.default
    if f.default_factory is not MISSING:
        return f.default_factory()
    return REQUIRED


def choices_of(meta: Any) -> list[str] | None:
    choices = meta.get("choices")
    if choices is None:
        return None
    return list(choices() if callable(choices) else choices)


# --- reading ----------------------------------------------------------------------------------------------

_NOTICES: set[str] = set()


def notice(text: str) -> None:
    """A one-line notice on stderr, once per process (a deprecated key or option)."""
    if text not in _NOTICES:
        _NOTICES.add(text)
        print(f"notice: {text}", file=sys.stderr)


def read(cls: type, data: Any, path: str, others: Iterable[str] = ()) -> Any:
    """The mapping ``data`` (at key path ``path``; "" for the top level) as an instance of Settings class
    ``cls``, read strictly (module docstring): a key neither declared nor in ``others`` is an error. ``data``
    may be a Section already."""
    sec = data if isinstance(data, Section) else Section(data, path)
    obj = _instance(cls, sec)
    sec.mark(*others)
    sec.finish()
    return obj


def read_entries(cls: type, data: Any, path: str) -> dict[str, Any]:
    """A mapping of named entries (``sensors: {radar: {…}, …}``), each read as ``cls``; names are letters,
    digits and underscores (they name nodes, topics and parameters)."""
    sub = data if isinstance(data, Section) else Section(data, path)
    out = {}
    for name in sub.keys():
        if not isinstance(name, str) or not name.replace("_", "").isalnum():
            raise ScenarioError(f"'{sub._key(str(name))}': a name must be letters, digits and underscores")
        out[name] = read(cls, sub.section(name), sub._key(name))
    sub.finish()
    return out


def read_key(cls: type, data: Any, key: str, path: str = "") -> Any:
    """The one key ``key`` that ``cls`` declares, read from the mapping ``data`` as :func:`read` reads it
    (its type, default, check and old names), ignoring the mapping's other keys."""
    for f, hint in fields_of(cls):
        if f.name == key:
            return _read_key(Section(data, path), f, hint)
    raise KeyError(f"{cls.__name__} declares no key {key!r}")


def _instance(cls: type, sec: Section) -> Any:
    values: dict[str, Any] = {}
    for f, hint in fields_of(cls):
        var = f.metadata.get("variant")
        if var is not None:
            values[f.name] = _read_variant(var, f.name, sec, values)
        else:
            values[f.name] = _read_key(sec, f, hint)
    obj = cls(**values)
    object.__setattr__(obj, "_path", sec.path)
    obj.validate(sec.path)
    return obj


def _read_variant(var: Variant, key: str, sec: Section, values: dict) -> Any:
    chosen = values[var.selected_by]
    option = var.load(chosen) if chosen is not None else None
    if option is None:
        return None
    if var.inline:
        return _instance(option, sec)
    return read(option, sec.section(key), sec._key(key))


def _read_key(sec: Section, f: dataclasses.Field, hint: Any) -> Any:
    key, meta, sh = f.name, f.metadata, shape(hint)
    default = default_of(f)
    for old in meta.get("old", ()):
        if old in sec.data:
            sec.mark(old)
            if key in sec.data:
                raise ScenarioError(f"'{sec._key(old)}' and '{sec._key(key)}' are one setting: keep '{key}' only")
            notice(f"the scenario key '{sec._key(old)}' is deprecated: call it '{sec._key(key)}'")
            sec = Section({**sec.data, key: sec.data[old]}, sec.path)  # a view with the new name
    if sh.settings is not None and (isinstance(sec.data.get(key), dict) or sh.kinds == (dict,)):
        return _read_nested(sec, key, sh, default)
    if object in sh.kinds:  # any value (an annotation-less estimator parameter)
        sec.mark(key)
        value = sec.data.get(key)
        if value is None and default is REQUIRED:
            raise ScenarioError(f"missing key '{sec._key(key)}'")
        return default if value is None else value
    kinds = tuple(k for k in sh.kinds if k is not dict) if sh.settings else sh.kinds
    value = sec.get(key, kinds, ... if default is REQUIRED else default)
    if value is default or value is None:
        return value
    if isinstance(value, list):
        value = _read_list(value, sh, sec._key(key))
    choices = choices_of(meta)
    if choices is not None and value not in choices:
        raise ScenarioError(f"'{sec._key(key)}' must be one of {choices}, got {value!r}")
    check = meta.get("check")
    if check is not None and not check.test(value):
        raise ScenarioError(f"'{sec._key(key)}' must be {check.text}, got {value!r}")
    return value


def _read_list(values: list, sh: Shape, path: str) -> list:
    if sh.item is None:
        return values
    try:
        return [_item(v, sh.item) for v in values]
    except (TypeError, ValueError):
        raise ScenarioError(f"'{path}' must be a list of {TYPE_TEXT[sh.item]}s, got {values!r}") from None


def _item(value: Any, kind: type) -> Any:
    if isinstance(value, bool) != (kind is bool):
        raise TypeError(value)
    if kind is float:
        return float(value)
    if not isinstance(value, kind):
        raise TypeError(value)
    return value


def _read_nested(sec: Section, key: str, sh: Shape, default: Any) -> Any:
    if sec.data.get(key) is None and default is not REQUIRED:
        sec.mark(key)
        return default
    sub = sec.section(key, default_empty=default is not REQUIRED)
    return read_entries(sh.settings, sub, sub.path) if sh.entries else read(sh.settings, sub, sub.path)


# --- types without checks (ROS parameters) ----------------------------------------------------------------


def coerce(cls: type, data: Any) -> Any:
    """A copy of the mapping ``data`` whose values of keys ``cls`` declares have their declared types (a
    ``float`` key's integer or numeric text becomes a float) and whose deprecated keys have their names of
    today; nothing is checked, no default added, and what cannot be converted is left as it is (validation
    reports it)."""
    if not isinstance(data, dict):
        return data
    out = dict(data)
    for f, hint in fields_of(cls):
        var = f.metadata.get("variant")
        if var is not None:
            option = _option(var, out)
            if option is not None:
                if var.inline:
                    out = coerce(option, out)
                elif f.name in out:
                    out[f.name] = coerce(option, out[f.name])
            continue
        for key in f.metadata.get("old", ()):
            if key in out and f.name not in out:
                out[f.name] = out.pop(key)
        if f.name in out:
            out[f.name] = _coerce_value(out[f.name], shape(hint))
    return out


def _option(var: Variant, data: dict) -> type | None:
    try:
        chosen = data.get(var.selected_by)
        return var.load(chosen) if chosen in set(var.names()) else None
    except (ScenarioError, TypeError):
        return None


def _coerce_value(value: Any, sh: Shape) -> Any:
    if sh.settings is not None and isinstance(value, dict):
        return {k: coerce(sh.settings, v) for k, v in value.items()} if sh.entries else coerce(sh.settings, value)
    if float in sh.kinds and isinstance(value, (int, str)) and not isinstance(value, bool):
        try:
            return float(value)
        except ValueError:
            return value
    if isinstance(value, list) and sh.item is float:
        try:
            return [_item(v, float) for v in value]
        except (TypeError, ValueError):
            return value
    return value


def join(prefix: str, key: str) -> str:
    """The key path of ``key`` under ``prefix``."""
    return f"{prefix}.{key}" if prefix else key


# --- registered sections ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class SectionReader:
    """The reader of one top-level scenario section, registered under ``tracking_bench.sections`` with the
    section's key as its name. ``schema``: a Settings class (the section is one mapping) or ``dict[str, X]`` (a
    mapping of named entries of Settings class X); ``read(cfg)``: the typed section (default: the section read
    with ``schema``), for a reader that needs more of the scenario (defaults merged in, names of other
    sections). ``defaults_of``: this section holds defaults for the entries of that one (``filter_defaults``:
    any key of ``filters.<name>``). Called with the scenario, it returns the typed section."""

    key: str
    schema: Any
    doc: str
    read: Callable[[dict], Any] | None = None
    defaults_of: str = ""

    def __call__(self, cfg: dict) -> Any:
        if self.read is not None:
            return self.read(cfg)
        sh = shape(self.schema)
        data = cfg.get(self.key)
        if sh.entries:
            return read_entries(sh.settings, data, self.key)
        return read(sh.settings, data, self.key)

    def coerce(self, data: Any) -> Any:
        """:func:`coerce` of this section's value."""
        sh = shape(self.schema)
        if sh.entries and isinstance(data, dict):
            return {k: coerce(sh.settings, v) for k, v in data.items()}
        return coerce(sh.settings, data)
