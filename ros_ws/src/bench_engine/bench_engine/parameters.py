"""A node's settings as ROS parameters: the part of the scenario its core reads, flattened, and back.

Contract: a node's parameter names are the scenario's own keys, joined by dots (``filters.ukf.params.alpha``
is what ``--set filters.ukf.params.alpha=0.5`` sets on the launcher), so one vocabulary serves the scenario
YAML, the launcher's overrides, a ``ros__parameters`` file and ``ros2 param get``. Each node kind says which
part of the scenario its core reads (``NodeKind.reads``); the launcher writes that part as the node's
parameters file, the node declares every parameter read-only and rebuilds its configuration from them alone.

A parameter has the type the scenario key is declared with (bench_engine.settings: a ``float`` key is a
double). ROS parameters hold booleans, integers, doubles, strings and non-empty arrays of one of those types. A
value that is none of these (null, an empty list, a list of lists or mappings, a list mixing strings and
numbers) and a mapping whose keys are not parameter-name tokens are stored as a string parameter holding
their YAML, named with the suffix :data:`YAML_SUFFIX` (``sensors.gnss1.outages__yaml: "[[3600, 4200]]"``). A
list mixing integers and doubles becomes doubles.

No rclpy here: the ROS shell (bench_engine.bench_node) declares and reads what these functions produce.
"""

from __future__ import annotations

import re
from typing import Any

import yaml

from bench_engine import yamlio
from bench_engine.config import ScenarioError
from bench_engine.graph import node_kinds
from bench_engine.scenario import coerce_scenario

YAML_SUFFIX = "__yaml"
"""Suffix of a parameter whose string value is the YAML of a value ROS parameters cannot hold."""
TOKEN = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
"""A key that can be one dot-separated part of a parameter name (and does not end like YAML_SUFFIX)."""
SCALARS = (bool, int, float, str)


def _is_token(key: Any) -> bool:
    return isinstance(key, str) and bool(TOKEN.match(key)) and not key.endswith(YAML_SUFFIX)


def _array(values: list) -> list | None:
    """``values`` as a ROS parameter array, or None if it cannot be one."""
    if not values or any(not isinstance(v, SCALARS) for v in values):
        return None
    kinds = {bool if isinstance(v, bool) else str if isinstance(v, str) else float for v in values}
    if len(kinds) != 1:
        return None
    if kinds == {float} and not all(isinstance(v, int) for v in values):
        return [float(v) for v in values]
    return list(values)


def _yaml_text(value: Any) -> str:
    """One line of YAML (a lone scalar such as null without the document end marker YAML adds to it)."""
    return yamlio.dump(value, default_flow_style=True, width=1 << 30).removesuffix("...\n").strip()


def flatten(tree: dict, prefix: str = "") -> dict[str, Any]:
    """Nested scenario mapping -> {dotted parameter name: ROS-representable value}."""
    flat: dict[str, Any] = {}
    for key, value in tree.items():
        if not _is_token(key):
            raise ScenarioError(
                f"'{prefix}{key}' cannot be a ROS parameter name: keys must be letters, digits "
                f"and underscores, starting with a letter"
            )
        name = f"{prefix}{key}"
        if isinstance(value, dict) and value and all(_is_token(k) for k in value):
            flat.update(flatten(value, name + "."))
        elif isinstance(value, SCALARS):
            flat[name] = value
        elif isinstance(value, list) and _array(value) is not None:
            flat[name] = _array(value)
        else:
            flat[name + YAML_SUFFIX] = _yaml_text(value)
    return flat


def unflatten(flat: dict[str, Any]) -> dict:
    """{dotted parameter name: value} -> nested mapping (inverse of :func:`flatten`)."""
    tree: dict = {}
    for name, value in sorted(flat.items()):
        if name.endswith(YAML_SUFFIX):
            name, value = name[: -len(YAML_SUFFIX)], _load_yaml(name, value)
        *parents, leaf = name.split(".")
        node = tree
        for i, part in enumerate(parents):
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise ScenarioError(f"parameter '{name}' lies under '{'.'.join(parents[: i + 1])}', which is a value")
        if isinstance(node.get(leaf), dict):
            raise ScenarioError(f"parameter '{name}' is both a value and a group of parameters")
        node[leaf] = list(value) if isinstance(value, (list, tuple)) else value
    return tree


def _load_yaml(name: str, text: Any) -> Any:
    if not isinstance(text, str):
        raise ScenarioError(f"parameter '{name}' must be a string holding YAML, got {text!r}")
    try:
        return yamlio.load(text)
    except yaml.YAMLError as err:
        raise ScenarioError(f"parameter '{name}' holds no valid YAML: {str(err).splitlines()[0]}") from None


def node_parameters(cfg: dict, kind: str, name: str) -> dict[str, Any]:
    """Node ``name``'s ROS parameters: its kind's part of the scenario (``NodeKind.settings``), every declared key
    of its declared type (bench_engine.scenario.coerce_scenario: a ``float`` key is a double even where the file
    writes an integer or YAML 1.1 reads the number as text), flattened."""
    return flatten(coerce_scenario(node_kinds()[kind].settings(cfg, name)))


def node_settings(cfg: dict, kind: str, name: str) -> dict:
    """Node ``name``'s settings as they reach it through ROS parameters (:func:`node_parameters`, read back), so
    validation and the in-process runner see what the node sees."""
    return unflatten(node_parameters(cfg, kind, name))


class _Quoted(str):
    """A string value, always written quoted: rcl's parser reads an unquoted scalar as a bool, an integer or a
    double whenever it can (``3.986004418e14``, ``y``, ``0x1F``), where PyYAML's YAML 1.1 rules see a string."""


class _ParametersDumper(yamlio.DUMPER):
    pass


_ParametersDumper.add_representer(
    _Quoted, lambda dumper, text: dumper.represent_scalar("tag:yaml.org,2002:str", str(text), style="'")
)


def _quoted(value: Any) -> Any:
    if isinstance(value, str):
        return _Quoted(value)
    return [_quoted(v) for v in value] if isinstance(value, list) else value


def parameters_file(flat: dict[str, Any], node: str = "/**") -> str:
    """The text of a ``--params-file`` for ``node`` (default: any node, so a renamed node still reads it)."""
    body = {name: _quoted(value) for name, value in flat.items()}
    return yaml.dump({node: {"ros__parameters": body}}, Dumper=_ParametersDumper, sort_keys=True, width=1 << 30)


def description(name: str) -> str:
    """What ``ros2 param describe`` shows for a scenario parameter."""
    key = name[: -len(YAML_SUFFIX)] + " (YAML text)" if name.endswith(YAML_SUFFIX) else name
    return (
        f"scenario key {key}: read once at start-up (read-only); set it in the scenario YAML, with the "
        f"launcher's --set, or in this node's parameters file"
    )
