"""Property test (hypothesis): any override of any scenario key gives either a valid run plan or a clean
ScenarioError naming what is wrong, never another exception (a traceback for the user)."""

from __future__ import annotations

import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench_engine.config import ScenarioError, apply_overrides, available_scenarios, load_scenario, override_strings
from bench_engine.graph import build_graph, resolve_estimators
from bench_engine.launcher import validate


def leaf_paths(node, prefix=()) -> list[str]:
    if isinstance(node, dict) and node:
        return [p for k, v in node.items() for p in leaf_paths(v, prefix + (str(k),))]
    return [".".join(prefix)] if prefix else []


SCENARIOS = tuple(available_scenarios())
"""Every registered study's scenario."""
PATHS = {
    name: [p for p in leaf_paths(load_scenario(name)) if not p.startswith(("sweeps", "variants", "description"))]
    for name in SCENARIOS
}
VALUES = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**12), 10**12),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8),
    st.lists(st.floats(-1e3, 1e3), max_size=7),
    st.dictionaries(st.text(max_size=4), st.integers(), max_size=2),
)


def plan_or_clean_error(scenario: str, overrides: dict) -> None:
    try:
        cfg = apply_overrides(load_scenario(scenario), override_strings(overrides))
        filters = resolve_estimators(cfg, None)
        validate(cfg, filters, "truth")
        build_graph(cfg, filters)
    except ScenarioError as err:
        assert str(err) and "\n" not in str(err).strip()


@pytest.mark.parametrize("scenario", SCENARIOS)
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
@given(data=st.data())
def test_any_override_gives_a_run_plan_or_a_clean_error(scenario: str, data) -> None:
    keys = data.draw(
        st.lists(
            st.one_of(st.sampled_from(PATHS[scenario]), st.sampled_from(PATHS[scenario]).map(lambda p: p + ".extra")),
            min_size=1,
            max_size=3,
            unique=True,
        )
    )
    overrides = {k: data.draw(VALUES) for k in keys}
    if any(isinstance(v, float) and math.isnan(v) for v in overrides.values()):
        overrides = {k: (".nan" if isinstance(v, float) and math.isnan(v) else v) for k, v in overrides.items()}
    plan_or_clean_error(scenario, overrides)
