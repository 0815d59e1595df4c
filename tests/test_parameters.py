"""A node's settings as ROS parameters (bench_engine.parameters): flatten/unflatten round-trip any scenario-like
tree, every node of every study gets exactly its kind's settings back, and rcl's own parser reads the
parameters files the launcher writes as the values written (types included)."""

from __future__ import annotations

import math
import re

import pytest
import rclpy
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.node import Node

from bench_engine import plugins
from bench_engine.config import ScenarioError, load_scenario
from bench_engine.graph import build_graph, node_kinds, resolve_estimators
from bench_engine.parameters import YAML_SUFFIX, flatten, node_parameters, node_settings, parameters_file, unflatten
from bench_engine.scenario import coerce_scenario
from bench_engine.settings_reference import entries

KEYS = st.from_regex(r"[a-z][a-z0-9_]{0,8}", fullmatch=True).filter(lambda k: not k.endswith(YAML_SUFFIX))
SCALAR = st.one_of(
    st.booleans(), st.integers(-(2**62), 2**62), st.floats(allow_nan=False, width=64), st.text(max_size=12)
)
LEAF = st.one_of(
    SCALAR, st.none(), st.lists(SCALAR, max_size=4), st.lists(st.lists(st.integers(), max_size=3), max_size=3)
)
TREES = st.recursive(
    st.dictionaries(KEYS, LEAF, max_size=4),
    lambda children: st.dictionaries(KEYS, st.one_of(LEAF, children), max_size=4),
    max_leaves=20,
)


def _numbers_as_floats(value):
    """What a list mixing integers and doubles becomes (doubles); everything else is unchanged."""
    if isinstance(value, dict):
        return {k: _numbers_as_floats(v) for k, v in value.items()}
    if (
        isinstance(value, list)
        and value
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
        and not all(isinstance(v, int) for v in value)
    ):
        return [float(v) for v in value]
    return value


@settings(max_examples=300, deadline=None)
@given(TREES)
def test_flatten_then_unflatten_gives_the_tree_back(tree: dict) -> None:
    flat = flatten(tree)
    for name, value in flat.items():
        assert all(part for part in name.split("."))
        assert isinstance(value, (bool, int, float, str, list))
        if isinstance(value, list):
            assert value and len({type(v) for v in value}) == 1
    assert unflatten(flat) == _numbers_as_floats(tree)


def test_values_ros_cannot_hold_travel_as_yaml_text() -> None:
    flat = flatten({"sensors": {"gnss1": {"outages": [[3600, 4200]], "bias": None, "tags": []}}, "n": [1, 2.5]})
    assert flat == {
        f"sensors.gnss1.outages{YAML_SUFFIX}": "[[3600, 4200]]",
        f"sensors.gnss1.bias{YAML_SUFFIX}": "null",
        f"sensors.gnss1.tags{YAML_SUFFIX}": "[]",
        "n": [1.0, 2.5],
    }
    assert unflatten(flat)["sensors"]["gnss1"] == {"outages": [[3600, 4200]], "bias": None, "tags": []}


@pytest.mark.parametrize("bad", [{"1x": 1}, {"a.b": 1}, {"a": {"b-c": 1, "d": 2}, "e f": 3}])
def test_a_key_that_cannot_be_a_parameter_name_is_named(bad: dict) -> None:
    if "a" in bad:  # a mapping with a bad key is kept whole as YAML; the bad top-level key is refused
        with pytest.raises(ScenarioError, match="'e f' cannot be a ROS parameter name"):
            flatten(bad)
        assert unflatten(flatten({"a": bad["a"]})) == {"a": bad["a"]}
        return
    with pytest.raises(ScenarioError, match="cannot be a ROS parameter name"):
        flatten(bad)


def test_conflicting_parameters_are_refused() -> None:
    with pytest.raises(ScenarioError, match="'a.b' lies under 'a'"):
        unflatten({"a": 1, "a.b": 2})
    with pytest.raises(ScenarioError, match="holds no valid YAML"):
        unflatten({f"x{YAML_SUFFIX}": "[1, 2"})


@pytest.mark.parametrize("scenario", sorted(plugins.names("scenarios")))
def test_every_node_of_every_study_gets_its_kinds_settings_back(scenario: str) -> None:
    cfg = load_scenario(scenario)
    graph = build_graph(cfg, resolve_estimators(cfg, None))
    for spec in graph.nodes:
        assert node_settings(cfg, spec.kind, spec.name) == _numbers_as_floats(
            coerce_scenario(node_kinds()[spec.kind].settings(cfg, spec.name))
        ), spec.name


def test_a_filter_is_given_its_own_settings_and_the_models_it_reads_only() -> None:
    cfg = load_scenario("leo_radar")
    settings_ = node_kinds()["filter"].settings(cfg, "ukf")
    assert set(settings_["filters"]) == {"ukf"} and "filter_defaults" not in settings_
    assert settings_["filters"]["ukf"]["type"] == "ukf" and "dynamics" in settings_["filters"]["ukf"]
    assert "variants" not in settings_ and "scoring" not in settings_


@pytest.mark.parametrize("scenario", ["leo_radar", "grace_velocity", "star_tracker"])
def test_rcl_reads_the_parameters_files_as_written(tmp_path, scenario: str) -> None:
    cfg = load_scenario(scenario)
    graph = build_graph(cfg, resolve_estimators(cfg, None))
    context = rclpy.Context()
    files = []
    for spec in graph.nodes:
        path = tmp_path / f"{spec.name}.yaml"
        path.write_text(parameters_file(node_parameters(cfg, spec.kind, spec.name), node=spec.name))
        files += ["--params-file", str(path)]
    rclpy.init(args=["test", "--ros-args", *files], context=context)
    try:
        for spec in graph.nodes:
            node = Node(spec.name, context=context, automatically_declare_parameters_from_overrides=True)
            flat = node_parameters(cfg, spec.kind, spec.name)
            for name, value in flat.items():
                got = node.get_parameter(name).value
                assert type(got if not isinstance(got, (list, tuple)) else got[0]) is type(
                    value if not isinstance(value, list) else value[0]
                ), name
                if isinstance(value, float) and math.isnan(value):
                    assert math.isnan(got)
                else:
                    assert (list(got) if isinstance(got, (list, tuple)) else got) == value, name
            node.destroy_node()
    finally:
        rclpy.shutdown(context=context)


NUMBERS = [
    re.compile("^" + re.escape(e.path).replace(re.escape("<name>"), "[A-Za-z0-9_]+") + "$")
    for e in entries()
    if e.type.startswith("number")
]
"""Key paths the settings declare as numbers (``float``)."""


@pytest.mark.parametrize("scenario", sorted(plugins.names("scenarios")))
def test_a_key_declared_a_number_is_a_double_parameter(scenario: str) -> None:
    """Whatever the YAML writes (an integer, or 3.986004418e14, which YAML 1.1 reads as text), a key declared as
    a number is a double parameter: ``ros2 param get`` shows it as one."""
    cfg = load_scenario(scenario)
    checked = 0
    for spec in build_graph(cfg, resolve_estimators(cfg, None)).nodes:
        for name, value in node_parameters(cfg, spec.kind, spec.name).items():
            if any(p.match(name) for p in NUMBERS) and value is not None:
                values = value if isinstance(value, list) else [value]
                assert all(type(v) is float for v in values), (spec.name, name, value)
                checked += 1
    assert checked > 0


def test_earth_mu_is_a_double_whatever_yaml_1_1_reads(tmp_path) -> None:
    cfg = load_scenario("leo_radar", ["earth.mu=3.986004418e14"])  # YAML 1.1: a string
    assert cfg["earth"]["mu"] == "3.986004418e14"
    flat = node_parameters(cfg, "filter", "ukf")
    assert flat["earth.mu"] == 3.986004418e14 and type(flat["earth.mu"]) is float
    path = tmp_path / "ukf.yaml"
    path.write_text(parameters_file(flat, node="ukf"))
    context = rclpy.Context()
    rclpy.init(args=["test", "--ros-args", "--params-file", str(path)], context=context)
    try:
        node = Node("ukf", context=context, automatically_declare_parameters_from_overrides=True)
        parameter = node.get_parameter("earth.mu")
        assert parameter.type_ == rclpy.Parameter.Type.DOUBLE and parameter.value == 3.986004418e14
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
