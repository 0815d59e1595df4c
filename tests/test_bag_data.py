"""The scorer's truth lookup by step (bench_eval.bag_data.BagData.truth_at): the same answer as the truth dict,
for steps in any order, missing steps, a truth stored out of step order, a truth changed after a lookup, and none.
And a BagData pickled (to and from scoring workers) with its values by step packed into arrays where they allow."""

from __future__ import annotations

import pickle

import numpy as np

from bench_eval.bag_data import BagData, PerStep


def _run(truth: dict) -> BagData:
    data = BagData({"scenario": {"scenario": "x"}, "estimators": []})
    data.truth = truth
    return data


def test_truth_at_matches_the_dict_for_any_steps() -> None:
    rng = np.random.default_rng(3)
    steps = rng.permutation(50)[:30]  # stored out of order, with gaps
    data = _run({int(k): (0.5 * k, rng.normal(size=4)) for k in steps})
    asked = np.array([7, -1, *steps[:5], 49, 1000])
    covered, t, states = data.truth_at(asked)
    assert covered.tolist() == [int(k) in data.truth for k in asked]
    assert t.tolist() == [data.truth[int(k)][0] for k in asked[covered]]
    np.testing.assert_array_equal(states, [data.truth[int(k)][1] for k in asked[covered]])
    assert data.truth_span() == (0.5 * steps.min(), 0.5 * steps.max())


def test_truth_at_follows_a_truth_replaced_after_a_lookup() -> None:
    data = _run({1: (1.0, np.zeros(2))})
    assert data.truth_at(np.array([2]))[0].tolist() == [False]
    data.truth = {2: (2.0, np.ones(2))}
    covered, t, states = data.truth_at(np.array([2]))
    assert covered.tolist() == [True] and t.tolist() == [2.0] and states.tolist() == [[1.0, 1.0]]


def test_truth_at_without_a_truth_covers_nothing() -> None:
    covered, t, states = _run({}).truth_at(np.array([0, 1]))
    assert covered.tolist() == [False, False] and len(t) == 0 and len(states) == 0


def test_a_pickled_run_has_the_same_values_by_step_packed_where_they_allow() -> None:
    rng = np.random.default_rng(5)
    steps = rng.permutation(40)  # out of order: the dicts' order is kept
    data = _run({int(k): (0.1 * k, rng.normal(size=6)) for k in steps})
    data.measurements = {
        "radar": {int(k): rng.normal(size=3) for k in steps[:25]},
        "camera": {int(k): rng.normal(size=(int(k) % 4, 2)) for k in steps},  # a varying number of centroids
        "silent": {},
    }
    state = data.__getstate__()
    assert isinstance(state["truth"], PerStep) and isinstance(state["measurements"]["radar"], PerStep)
    assert state["measurements"]["camera"] is data.measurements["camera"] and state["measurements"]["silent"] == {}
    copy = pickle.loads(pickle.dumps(data))
    assert list(copy.truth) == list(data.truth) and all(type(k) is int for k in copy.truth)
    for k, (t, x) in data.truth.items():
        assert copy.truth[k][0] == t and np.array_equal(copy.truth[k][1], x)
    for name, by_step in data.measurements.items():
        assert list(copy.measurements[name]) == list(by_step)
        assert all(np.array_equal(copy.measurements[name][k], z) for k, z in by_step.items())
    np.testing.assert_array_equal(copy.truth_at(steps[:5])[2], data.truth_at(steps[:5])[2])
