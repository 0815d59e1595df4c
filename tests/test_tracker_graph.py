"""Detection sets and the tracker through the real ROS 2 graph (one process per node, DDS on this host):
formation_cqkf's linear 1 km case shortened to 60 s (tests/data/tracker_formation.yaml), a cluttered sensor
publishing bench_msgs/DetectionSet, and the GNN tracker next to the plain CQKF. The bag is read back with
rosbags; the graph carries exactly what the same cores give in process (codec round trip, seeded streams)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from graph_helpers import read_bag, script, stamp

from bench_engine.config import load_scenario
from bench_engine.inprocess import run_in_process

SCENARIO = Path(__file__).parent / "data" / "tracker_formation.yaml"
SIGMA = 0.0316227766  # m, the relative-position noise of both sensors


@pytest.fixture(scope="module")
def graph_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("tracker_graph")
    res = script("launch.py", str(SCENARIO), "--seed", "2", "--out", str(out), "--json")
    assert res.returncode == 0, res.stderr[-3000:]
    return out, read_bag(out / "bag"), json.loads(res.stdout)


def test_the_detection_sets_are_in_the_bag(graph_run):
    out, bag, _ = graph_run
    assert {"/truth/state", "/isl/measurement", "/cam/detections", "/cw/estimate", "/gnn/estimate"} <= set(bag)
    sets = [m for _, m in bag["/cam/detections"]]
    assert [m.step for m in sets] == list(range(61))  # one set per 1 s step, empty ones too
    assert all(stamp(m) == pytest.approx(m.step) for m in sets)
    assert all(list(m.labels) == ["x", "y", "z"] and m.sensor_id == "cam" and m.header.frame_id == "lvlh" for m in sets)
    counts = np.array([len(m.values) // 3 for m in sets])
    assert all(len(m.values) == 3 * n and len(m.covariance) == 9 * n for m, n in zip(sets, counts))
    assert 1.5 < counts.mean() < 4.5  # P_D 0.9 + Poisson(2) clutter
    for m, n in zip(sets, counts):
        np.testing.assert_array_equal(
            np.asarray(m.covariance).reshape(n, 3, 3), np.tile(SIGMA**2 * np.eye(3), (n, 1, 1))
        )
    # the target's detection is in most sets, within 5 sigma of the true position; clutter spreads +-100 m
    truth = {m.step: np.asarray(m.state) for _, m in bag["/truth/state"]}
    Z = [np.asarray(m.values).reshape(-1, 3) for m in sets]
    hit = [np.any(np.linalg.norm(z - truth[m.step][:3], axis=1) < 5 * SIGMA) for m, z in zip(sets, Z)]
    assert 0.75 <= np.mean(hit) < 1.0
    spread = np.vstack([z - truth[m.step][:3] for m, z in zip(sets, Z)])
    assert np.all(np.abs(spread) <= 100.0 + 5 * SIGMA) and np.max(np.abs(spread)) > 50.0


def test_the_graph_carries_what_the_cores_give_in_process(graph_run):
    _, bag, _ = graph_run
    run = run_in_process(load_scenario(str(SCENARIO)), None, seed=2)
    sets = [m for _, m in bag["/cam/detections"]]
    assert len(sets) == len(run.items["/cam/detections"])
    for m, d in zip(sets, run.items["/cam/detections"]):
        np.testing.assert_array_equal(np.asarray(m.values).reshape(-1, 3), d.Z)
    estimates = [m for _, m in bag["/gnn/estimate"]]
    assert len(estimates) == len(run.items["/gnn/estimate"]) > 50
    for m, e in zip(estimates, run.items["/gnn/estimate"]):
        assert m.step == e.step and m.filter_name == "gnn"
        np.testing.assert_allclose(m.state, e.x, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(np.asarray(m.covariance).reshape(6, 6), e.P, rtol=1e-12, atol=1e-15)


def test_the_tracker_estimates_are_accurate_and_scored(graph_run):
    _, bag, score = graph_run
    truth = {m.step: np.asarray(m.state) for _, m in bag["/truth/state"]}
    estimates = [m for _, m in bag["/gnn/estimate"]]
    first_set = next(m.step for _, m in bag["/cam/detections"] if len(m.values))
    assert [m.step for m in estimates] == list(range(first_set, 61))  # one estimate per set once started
    assert list(estimates[0].labels) == ["x", "y", "z", "vx", "vy", "vz"]
    diag = [dict(zip(m.diagnostic_names, m.diagnostic_values)) for m in estimates]
    assert np.mean([d["associated"] for d in diag]) >= 0.75
    errors = np.array([np.asarray(m.state)[:3] - truth[m.step][:3] for m in estimates])
    sigmas = np.array([np.sqrt(np.diag(np.asarray(m.covariance).reshape(6, 6))[:3]) for m in estimates])
    assert np.all(np.abs(errors[10:]) < 5 * sigmas[10:])  # within 5 of its own sigmas once settled
    assert np.all(np.linalg.norm(errors[10:], axis=1) < 0.1)  # 10 cm: ~3 sensor sigmas, not 100 m clutter
    # the scorer scores the tracker like a filter, close to the clean filter's accuracy
    filters = score["estimators"]
    assert {"cw", "gnn"} <= set(filters)
    gnn, cw = filters["gnn"], filters["cw"]
    assert gnn["nees_bounds"][0] <= gnn["nees_mean"] <= gnn["nees_bounds"][1]
    for axis in ("x", "y", "z"):
        assert gnn["mae"][axis] < 2.0 * cw["mae"][axis] + 0.01, (axis, gnn["mae"], cw["mae"])


def test_a_bad_tracker_key_stops_the_launcher_before_any_node(tmp_path):
    res = script("launch.py", str(SCENARIO), "--out", str(tmp_path), "--set", "trackers.gnn.detections=isl", timeout=60)
    assert res.returncode == 2, res.stderr[-2000:]
    assert "trackers.gnn.detections" in res.stderr and not (tmp_path / "bag").exists()
