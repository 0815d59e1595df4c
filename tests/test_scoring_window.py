"""The scoring window (bench_eval.window): stated once in ``scoring.window``, read strictly, and applied by the
scorer to every estimator alike: all are scored over the same steps of the window, whatever their own spans,
rates and gaps, after the offline estimators ran over the whole run; the edges (head and tail) are scored apart."""

from __future__ import annotations

import numpy as np
import pytest

from bench_engine.config import ScenarioError, load_scenario
from bench_eval.scoring import BagData, Estimates, score_bags, scoring_options

LABELS = ["x", "y", "z", "vx", "vy", "vz"]
STEPS = 200


def _cfg(window: dict | None) -> dict:
    cfg = load_scenario("formation_cqkf")
    cfg["scoring"] = {"metric": "errors", "offline": {"ss_rts": {"estimator": "rts", "source": "ss"}}}
    if window is not None:
        cfg["scoring"]["window"] = window
    return cfg


@pytest.mark.parametrize(
    "window, message",
    [
        ({"head": 10.0}, "unknown key.*'scoring.window.head'"),
        ({"head_s": -1.0}, "'scoring.window.head_s' must be >= 0"),
        ({"tail_s": "late"}, "'scoring.window.tail_s' must be a number"),
        ({"edges": "yes"}, "'scoring.window.edges' must be true/false"),
        ({"head_s": 3000.0, "tail_s": 2952.8}, "leaves nothing of the run's 5952.8 s"),
    ],
)
def test_a_bad_window_is_refused_naming_its_key(window: dict, message: str) -> None:
    with pytest.raises(ScenarioError, match=message):
        scoring_options(_cfg(window))


def test_without_the_key_there_is_no_window() -> None:
    assert scoring_options(_cfg(None)).window is None
    window = scoring_options(_cfg({"tail_s": 5.0})).window
    assert (window.head_s, window.tail_s, window.edges) == (0.0, 5.0, False)


def _run(cfg: dict) -> BagData:
    """A run of 200 one-second steps: filter 'ss' (a random walk about the truth) at every step, 'late' from step
    40 with no estimate at step 150 and a NaN state at step 151, 'sparse' at every other step; the scenario's
    RTS smoother of 'ss' runs offline. The truth: a straight line."""
    rng = np.random.default_rng(5)
    t = np.arange(STEPS, dtype=float)
    truth = np.column_stack([t, 2.0 * t, np.zeros(STEPS), np.ones(STEPS), 2.0 * np.ones(STEPS), np.zeros(STEPS)])
    P = np.repeat(np.eye(6)[None], STEPS, 0)
    data = BagData(
        {"scenario": cfg, "estimators": ["ss", "late", "sparse"]},
        truth={k: (float(k), truth[k]) for k in range(STEPS)},
        truth_labels=list(LABELS),
    )
    data.measurements["isl"] = {k: np.zeros(3) for k in range(STEPS)}
    steps = np.arange(STEPS)
    data.estimates["ss"] = Estimates(steps, t, truth + rng.normal(0, 0.1, truth.shape), P, LABELS, {})
    late = steps[(steps >= 40) & (steps != 150)]
    x_late = truth[late] + 1.0
    x_late[late == 151] = np.nan
    data.estimates["late"] = Estimates(late, t[late], x_late, P[late], LABELS, {})
    sparse = steps[::2]
    data.estimates["sparse"] = Estimates(sparse, t[sparse], truth[sparse] - 0.5, P[sparse], LABELS, {})
    return data


def test_every_estimator_of_a_run_is_scored_over_the_same_steps_of_the_window() -> None:
    """head_s 20, tail_s 30: the window is steps 20..169; of those, every estimator (the filters and the offline
    smoother) is scored at the even steps from 40 on but 150 (absent) and 151 (NaN): the steps all of them have."""
    cfg = _cfg({"head_s": 20.0, "tail_s": 30.0})
    result, series = score_bags([_run(cfg)], with_series=True)
    expected = [k for k in range(40, 170, 2) if k not in (150, 151)]
    assert set(series) == {"ss", "late", "sparse", "ss_rts"}
    for name, s in series.items():  # the errors family's time axis starts at the first scored stamp
        np.testing.assert_array_equal(s["t"], np.array(expected) - expected[0], err_msg=name)
    assert result["window"] == {"head_s": 20.0, "tail_s": 30.0, "steps": [len(expected)]}
    # the scores are those of exactly these steps: 'late' is 1 m off on every axis, 'sparse' 0.5 m
    assert result["estimators"]["late"]["mae"]["x"] == pytest.approx(1.0)
    assert result["estimators"]["sparse"]["mae"]["y"] == pytest.approx(0.5)
    assert "edges" not in result["estimators"]["ss"]


@pytest.mark.filterwarnings("ignore:Mean of empty slice")  # 'late''s NaN state, scored as it is without a window
def test_without_a_window_each_estimator_keeps_its_own_steps() -> None:
    _, series = score_bags([_run(_cfg(None))], with_series=True)
    assert len(series["ss"]["t"]) == STEPS and len(series["sparse"]["t"]) == STEPS // 2
    assert series["late"]["t"][-1] - series["late"]["t"][0] == STEPS - 1 - 40


@pytest.mark.filterwarnings("ignore:Mean of empty slice")
def test_the_offline_estimators_run_over_the_whole_run_before_the_window_cuts_it() -> None:
    """The RTS smoother of 'ss' is the same whether the run is scored with a window or not: it used the data on
    both sides of the window (its last estimate, the filter's, is outside it)."""
    whole, cut = _run(_cfg(None)), _run(_cfg({"head_s": 20.0, "tail_s": 30.0}))
    score_bags([whole]), score_bags([cut])
    np.testing.assert_array_equal(whole.estimates["ss_rts"].x, cut.estimates["ss_rts"].x)
    assert len(cut.estimates["ss_rts"].steps) == STEPS


def test_the_edges_are_scored_apart_each_estimator_over_its_own_steps_there() -> None:
    cfg = _cfg({"head_s": 20.0, "tail_s": 30.0, "edges": True})
    result = score_bags([_run(cfg)])["estimators"]
    assert set(result["ss"]["edges"]) == {"head", "tail"}
    assert "head" not in result["late"].get("edges", {})  # 'late' has nothing in the first 20 s
    assert result["late"]["edges"]["tail"]["mae"]["x"] == pytest.approx(1.0)
    assert result["sparse"]["edges"]["head"]["mae"]["x"] == pytest.approx(0.5)


def test_an_estimator_without_any_estimate_in_the_window_is_left_out_and_named(capsys) -> None:
    data = _run(_cfg({"head_s": 20.0, "tail_s": 30.0}))
    late = data.estimates["late"]
    data.estimates["late"] = Estimates(np.arange(10), np.arange(10.0), late.x[:10], late.P[:10], LABELS, {})
    result = score_bags([data])
    assert "late" not in result["estimators"] and {"ss", "sparse", "ss_rts"} <= set(result["estimators"])
    assert "'late' has no estimate in the scoring window [20, 169] s" in capsys.readouterr().err
