"""Contracts the scorer relies on are stated and checked: which topics hold measurements and estimates
(bench_engine.graph.MEASUREMENT / ESTIMATE, refused by build_graph when broken), and which estimate
components are scored against which truth components (by label, wherever they sit: bench_eval.scoring.track_of)."""

from __future__ import annotations

import numpy as np
import pytest

from bench_engine.config import ScenarioError, load_scenario
from bench_engine.graph import (
    ESTIMATE,
    ESTIMATE_TYPE,
    MEASUREMENT,
    NodeKind,
    NodeSpec,
    _check_topic_contract,
    build_graph,
    owners,
    topic_owner,
)
from bench_eval.scoring import BagData, Estimates, track_of


@pytest.mark.parametrize(
    "topic, suffix, owner",
    [
        ("/radar/measurement", MEASUREMENT, "radar"),
        ("/ukf/estimate", ESTIMATE, "ukf"),
        ("/ukf/estimate", MEASUREMENT, None),
        ("/a/b/estimate", ESTIMATE, None),
        ("//estimate", ESTIMATE, None),
        ("ukf/estimate", ESTIMATE, None),
        ("/ukf/estimates", ESTIMATE, None),
    ],
)
def test_topic_owner_reads_only_the_contracted_shape(topic: str, suffix: str, owner: str | None) -> None:
    assert topic_owner(topic, suffix) == owner


@pytest.mark.parametrize(
    "spec, message",
    [
        (
            NodeSpec("ukf", "filter", "estimator", publishes={"/radar/measurement": "bench_msgs/msg/RangeAzEl"}),
            "only sensor 'radar' may",
        ),
        (NodeSpec("radar", "sensor", "sensor", publishes={"/ukf/estimate": ESTIMATE_TYPE}), "only estimator 'ukf'"),
        (
            NodeSpec("ukf", "filter", "estimator", publishes={"/ukf/estimate": "nav_msgs/msg/Odometry"}),
            "as nav_msgs/msg/Odometry",
        ),
        (NodeSpec("lag", "fixed_lag", "estimator", publishes={"/ukf/estimate": ESTIMATE_TYPE}), "only estimator 'ukf'"),
    ],
)
def test_the_graph_refuses_a_node_that_breaks_the_topic_contract(spec: NodeSpec, message: str) -> None:
    with pytest.raises(ScenarioError, match=message):
        _check_topic_contract([spec])


def test_the_player_republishes_measurements_and_a_sensor_its_own() -> None:
    _check_topic_contract(
        [
            NodeSpec("player", "player", "replay", publishes={"/radar/measurement": "x"}),
            NodeSpec("radar", "sensor", "sensor", publishes={"/radar/measurement": "x"}),
            NodeSpec("ukf", "filter", "estimator", publishes={"/ukf/estimate": ESTIMATE_TYPE}),
        ]
    )


def _bag(truth_labels: list[str], est_labels: list[str], x: np.ndarray, P: np.ndarray, truth: np.ndarray) -> BagData:
    data = BagData(
        {"scenario": {}, "estimators": ["f"]},
        truth={k: (float(k), truth[k]) for k in range(len(truth))},
        truth_labels=truth_labels,
    )
    data.estimates["f"] = Estimates(np.arange(len(x)), np.arange(len(x), dtype=float), x, P, est_labels, {})
    return data


def test_a_state_with_a_bias_block_first_is_scored_on_the_components_the_truth_has() -> None:
    rng = np.random.default_rng(4)
    truth_labels = ["vx", "vy", "vz", "x", "y", "z"]  # the truth's own order
    est_labels = ["bx", "by", "bz", "x", "y", "z", "vx", "vy", "vz"]
    x, truth = rng.normal(size=(5, 9)), rng.normal(size=(5, 6))
    A = rng.normal(size=(5, 9, 9))
    P = A @ np.swapaxes(A, 1, 2)
    track = track_of(_bag(truth_labels, est_labels, x, P, truth), "f")
    assert track.labels == ["x", "y", "z", "vx", "vy", "vz"]
    np.testing.assert_array_equal(track.x_est, x[:, 3:])
    np.testing.assert_array_equal(track.P, P[:, 3:, 3:])
    np.testing.assert_array_equal(track.x_true, truth[:, [3, 4, 5, 0, 1, 2]])


def test_an_attitude_with_rates_keeps_the_rotation_block_of_its_error_covariance() -> None:
    rng = np.random.default_rng(5)
    est_labels = ["wx", "qw", "qx", "qy", "qz"]  # error labels: wx rx ry rz
    q = rng.normal(size=(3, 4))
    x = np.column_stack([rng.normal(size=3), q / np.linalg.norm(q, axis=1, keepdims=True)])
    A = rng.normal(size=(3, 4, 4))
    P = A @ np.swapaxes(A, 1, 2)
    track = track_of(_bag(["qw", "qx", "qy", "qz"], est_labels, x, P, x[:, 1:]), "f")
    assert track.labels == ["qw", "qx", "qy", "qz"]
    np.testing.assert_array_equal(track.P, P[:, 1:, 1:])


def test_repeated_labels_are_refused_rather_than_matched_at_random() -> None:
    data = _bag(["x", "x"], ["x", "y"], np.zeros((1, 2)), np.zeros((1, 2, 2)), np.zeros((1, 2)))
    with pytest.raises(ValueError, match="repeats state labels"):
        track_of(data, "f")


def _kind(name: str, claims=None, takes_unclaimed: bool = False):
    return NodeKind(
        name,
        "estimator",
        "x:Y",
        instances=lambda cfg, names: names,
        spec=lambda cfg, n: NodeSpec(n, name),
        claims=claims,
        takes_unclaimed=takes_unclaimed,
    )


def test_each_selected_estimator_belongs_to_the_one_kind_whose_section_defines_it() -> None:
    filters = _kind("filter", lambda cfg: ["ukf"], takes_unclaimed=True)
    stars = _kind("star_tracker", lambda cfg: ["sna", "jpdaf"])
    lag = _kind("fixed_lag")
    assert owners({}, ["ukf", "sna", "cqkf"], [filters, stars, lag]) == {
        "filter": ["ukf", "cqkf"],
        "star_tracker": ["sna"],
    }
    with pytest.raises(ScenarioError, match="'sna' is defined by more than one"):
        owners({}, ["sna"], [filters, stars, _kind("other", lambda cfg: ["sna"])])
    with pytest.raises(ScenarioError, match="no section of the scenario defines estimator 'cqkf'"):
        owners({}, ["cqkf"], [stars])


def test_the_star_tracker_scenario_gives_its_trackers_to_their_kind_and_nothing_to_the_filters() -> None:
    cfg = load_scenario("star_tracker")
    kinds = {n.name: n.kind for n in build_graph(cfg, None, record=False).of_role("estimator")}
    assert set(kinds.values()) == {"star_tracker"} and set(kinds) == set(cfg["estimators"])
