"""Detection sets and the tracker layer: gating and global-nearest-neighbour association, a tracker that is
exactly its filter when there is nothing to associate, tracking in clutter, and a graph run read back with
rosbags."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from bench_engine.config import load_scenario
from bench_engine.inprocess import run_in_process
from bench_models.linear_models import PositionMeasurement
from graph_helpers import read_bag, script
from tracker_filters.association import NO_DETECTION, GlobalNearestNeighbour, hypothesise
from tracker_filters.builders import build_filter_stack
from tracker_filters.tracker import Tracker

DEMO = str(Path(__file__).parent / "data" / "clutter_demo.yaml")


def test_gating_and_gnn_on_a_hand_computed_case():
    """Two 1-D tracks at 0 and 10 (variance 1), detections at 0.5, 9.0, 30 (variance 1): S = 2, so d2 = 0.125,
    40.5, 450 for track 0 and 45.125, 0.5, 200 for track 1; the 99 % gate (6.63) keeps 0.125 and 0.5 only."""
    model = PositionMeasurement(1)
    x = [np.array([0.0, 0.0]), np.array([10.0, 0.0])]
    P = [np.eye(2), np.eye(2)]
    Z, R = np.array([[0.5], [9.0], [30.0]]), np.ones((3, 1, 1))
    hyp = hypothesise(x, P, Z, R, model, 0.0, 0.99)
    np.testing.assert_allclose(hyp.d2[0, 0], 0.125)
    np.testing.assert_allclose(hyp.d2[1, 1], 0.5)
    assert np.isinf(hyp.d2[0, 1]) and np.isinf(hyp.d2[1, 2]) and hyp.gate == pytest.approx(6.634897)
    assert GlobalNearestNeighbour().associate(hyp) == [0, 1]
    # one detection in both gates goes to the closer track; the other track is missed
    hyp = hypothesise(x, P, np.array([[4.0]]), np.full((1, 1, 1), 9.0), model, 0.0, 0.99)
    assert GlobalNearestNeighbour().associate(hyp) == [0, NO_DETECTION]
    assert GlobalNearestNeighbour().associate(hypothesise(x, P, np.zeros((0, 1)), np.zeros((0, 1, 1)), model,
                                                          0.0, 0.99)) == [NO_DETECTION, NO_DETECTION]


def test_without_clutter_and_misses_the_tracker_is_its_filter():
    cfg = load_scenario(DEMO)
    stack = build_filter_stack(cfg, "kf")
    sensor = stack.sensors["pos"]
    tracker = Tracker(lambda: build_filter_stack(cfg, "kf").filter,
                      lambda z, R, t: stack.initialise(z, R, sensor, t), sensor.model)
    run = run_in_process(cfg, ["kf"], seed=3)
    for m, est in zip(run.items["/pos/measurement"], run.items["/kf/estimate"]):
        tracker.step(m.t, m.z[None], m.R[None])
        flt = tracker.tracks[0].filter
        np.testing.assert_array_equal(flt.x, est.x)
        np.testing.assert_array_equal(flt.P, est.P)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_tracker_follows_the_target_through_clutter(seed):
    run = run_in_process(load_scenario(DEMO), ["kf"], seed=seed)
    truth = {s.step: s.state for s in run.items["/truth/state"]}
    sets = run.items["/cam/detections"]
    assert sum(len(d.Z) for d in sets) > 3 * len(sets)  # ~0.9 target + 3 clutter detections per step
    estimates = run.items["/gnn/estimate"]
    assert len(estimates) == len(sets)
    errors = np.array([np.linalg.norm(e.x[:3] - truth[e.step][:3]) for e in estimates])
    assert np.max(errors[20:]) < 2.0  # sigma 0.5 m per axis, clutter spread over +-15 m: never lured away
    assert np.mean([e.diagnostics["associated"] for e in estimates]) > 0.8


def test_detection_sets_and_tracks_through_the_graph(tmp_path: Path):
    res = script("launch.py", DEMO, "--out", str(tmp_path), "--json")
    assert res.returncode == 0, res.stderr[-2000:]
    bag = read_bag(tmp_path / "bag")
    sets = [m for _, m in bag["/cam/detections"]]
    assert len(sets) == 121 and all(len(m.values) == 3 * len(m.covariance) // 9 for m in sets)
    assert sorted(m.step for _, m in bag["/gnn/estimate"]) == list(range(121))
    scored = json.loads(res.stdout)["filters"]
    assert {"kf", "gnn"} <= set(scored) and scored["gnn"]["mae"]["x"] < 1.0
