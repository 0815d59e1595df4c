"""The scorer's truth lookup by step (bench_eval.bag_data.BagData.truth_at): the same answer as the truth dict,
for steps in any order, missing steps, a truth stored out of step order, a truth changed after a lookup, and none."""

from __future__ import annotations

import numpy as np

from bench_eval.bag_data import BagData


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
