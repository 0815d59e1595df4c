"""The in-process run drives the same cores as the ROS 2 graph: same seed, same numbers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from graph_helpers import read_bag, script

from bench_engine.config import load_scenario
from bench_engine.inprocess import run_in_process

CASES = {"leo_radar": ["ekf", "ukf"], "formation_cqkf": ["ss", "cwb"]}


@pytest.mark.parametrize("scenario", sorted(CASES))
def test_in_process_run_equals_the_graph_run(tmp_path: Path, scenario: str) -> None:
    filters = CASES[scenario]
    res = script(
        "launch.py",
        scenario,
        "--seed",
        "4",
        "--estimators",
        ",".join(filters),
        "--out",
        str(tmp_path),
        "--set",
        "time.duration=25",
        "--no-score",
        "--single-process",
    )
    assert res.returncode == 0, res.stderr[-2000:]
    bag = read_bag(tmp_path / "bag")
    run = run_in_process(load_scenario(scenario, ["time.duration=25"]), filters, seed=4)
    for topic, items in run.items.items():
        msgs = [m for _, m in bag[topic]]
        assert len(msgs) == len(items) > 0, topic
        assert [m.step for m in msgs] == [i.step for i in items]
    for name in filters:
        recorded = np.array([m.state for _, m in bag[f"/{name}/estimate"]])
        in_process = np.array([e.x for e in run.items[f"/{name}/estimate"]])
        np.testing.assert_array_equal(recorded, in_process)
    z_bag = np.array(
        [
            [m.range, m.azimuth, m.elevation] if hasattr(m, "range") else m.value
            for _, m in next(v for t, v in bag.items() if t.endswith("/measurement"))
        ]
    )
    z_run = np.array([m.z for m in next(v for t, v in run.items.items() if t.endswith("/measurement"))])
    np.testing.assert_array_equal(z_bag, z_run)


def test_in_process_run_stops_at_the_requested_step() -> None:
    run = run_in_process(load_scenario("formation_pf"), ["pf"], seed=1, until_step=9)
    assert [t.step for t in run.items["/truth/state"]] == list(range(10))
    assert len(run.items["/pf/estimate"]) == 10
