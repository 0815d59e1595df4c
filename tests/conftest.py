"""The order of `make test`'s parallel run (pytest-xdist, ``--dist loadfile --no-loadscope-reorder``): the slowest
modules first, so the workers end together instead of one running a long module alone at the end (longest
first). The list is a measured ranking (``pytest --durations``, summed per module, on an idle 2-core machine);
a module not named keeps its place after them. Order only: no test depends on another's."""

from __future__ import annotations

from pathlib import Path

import pytest

SLOWEST_FIRST = [
    "test_dask_executor.py",
    "test_launcher_robustness.py",
    "test_fuzz_readers.py",
    "test_chaos.py",
    "test_run_overhead.py",
    "test_bad_inputs.py",
    "test_star_graph.py",
    "test_colcon_workspace.py",
    "test_grace_graph.py",
    "test_graph.py",
    "test_bounds.py",
    "test_reproduce.py",
    "test_sweep.py",
    "test_bag_regression.py",
    "test_swappable_filters_graph.py",
    "test_sim_time_bags.py",
    "test_standard_outputs_graph.py",
    "test_orbit_fit.py",
    "test_leo_consistency.py",
    "test_scenario_properties.py",
    "test_package_dependencies.py",
    "test_cdr.py",
    "test_recovery.py",
    "test_registry.py",
    "test_bad_measurements_graph.py",
]


def pytest_collection_modifyitems(items) -> None:
    stale = [name for name in SLOWEST_FIRST if not (Path(__file__).parent / name).is_file()]
    if stale:
        raise pytest.UsageError(f"tests/conftest.py: SLOWEST_FIRST names no such module: {', '.join(stale)}")
    rank = {name: i for i, name in enumerate(SLOWEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: the others keep their order
