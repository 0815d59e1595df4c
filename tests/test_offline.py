"""The offline-estimator stage (bench_eval.offline): read strictly from ``scoring.offline``, run over a recorded
run's estimates by the generic scorer, and its output joins the estimates like another filter's."""

from __future__ import annotations

import numpy as np
import pytest

from bench_engine import plugins
from bench_engine.config import ScenarioError, load_scenario, select_variant
from bench_eval.scoring import BagData, Estimates, run_offline, scoring_options
from tracker_filters.builders import build_filter_stack

LABELS = ["x", "y", "z", "vx", "vy", "vz"]


def cqkf_with(offline) -> dict:
    cfg = load_scenario("formation_cqkf")
    cfg["scoring"] = {"metric": "errors", "offline": offline}
    return cfg


@pytest.mark.parametrize(
    "offline, message",
    [
        ({"s": {"estimator": "kalman_smoother", "source": "ss"}}, "'scoring.offline.s.estimator' must be one of"),
        ({"s": {"estimator": "rts", "source": "nope"}}, "source 'nope' is not a filter of the scenario"),
        ({"s": {"estimator": "rts", "sorce": "ss"}}, "missing key 'scoring.offline.s.source'"),
        ({"s": {"estimator": "rts", "source": "ss", "lag": 3}}, "lag"),
        (
            {"s": {"estimator": "rts", "source": "ss", "params": {"lag": 3}}},
            "unknown key\\(s\\) .scoring.offline.s.params.lag.",
        ),
    ],
)
def test_a_bad_offline_entry_is_refused_naming_it(offline, message):
    with pytest.raises(ScenarioError, match=message):
        scoring_options(cqkf_with(offline))


def test_the_registered_offline_estimators_and_the_study_variant():
    assert "rts" in plugins.names("offline")
    assert scoring_options(load_scenario("formation_cqkf")).offline == {}
    opts = scoring_options(select_variant(load_scenario("formation_cqkf"), "smoothed"))
    assert {n: (o.estimator, o.source) for n, o in opts.offline.items()} == {
        "ss_rts": ("rts", "ss"),
        "cw_rts": ("rts", "cw"),
        "cwb_rts": ("rts", "cwb"),
    }


def synthetic_run(cfg: dict, steps: int = 300, seed: int = 3) -> tuple[BagData, np.ndarray]:
    """A recorded run of filter "ss": the truth follows ss's own linear model with its process noise, and the
    filter is the exact Kalman filter of position measurements on that model. Returns (bag data, truth)."""
    rng = np.random.default_rng(seed)
    dyn = build_filter_stack(cfg, "ss").filter.dynamics
    dt, R, H = 1.0, np.eye(3) * 0.5**2, np.hstack([np.eye(3), np.zeros((3, 3))])
    x = np.array([0.0, 1000.0, 0.0, 0.5, 0.0, 0.2])
    m, P = x + rng.normal(0.0, [5, 5, 5, 0.05, 0.05, 0.05]), np.diag([25.0] * 3 + [0.0025] * 3)
    truth, xs, Ps = [], [], []
    for k in range(steps):
        if k:
            F, Q = dyn.transition_matrix(x, dt), dyn.process_noise(x, dt)
            x = F @ x + rng.multivariate_normal(np.zeros(6), Q)
            m, P = F @ m, F @ P @ F.T + Q
        z = H @ x + rng.normal(0.0, 0.5, 3)
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        m, P = m + K @ (z - H @ m), (np.eye(6) - K @ H) @ P
        truth.append(x), xs.append(m), Ps.append(P)
    data = BagData({"scenario": cfg, "estimators": ["ss"]})
    data.estimates["ss"] = Estimates(np.arange(steps), dt * np.arange(steps), np.array(xs), np.array(Ps), LABELS, {})
    data.truth = {k: (dt * k, t) for k, t in enumerate(truth)}
    data.truth_labels = LABELS
    return data, np.array(truth)


def test_the_scorer_runs_the_named_offline_estimator_and_its_output_is_a_better_track():
    cfg = cqkf_with({"ss_rts": {"estimator": "rts", "source": "ss"}, "cw_rts": {"estimator": "rts", "source": "cw"}})
    data, truth = synthetic_run(cfg)
    ran = run_offline(data, scoring_options(cfg))
    assert ran == ["ss_rts"]  # cw did not run in this bag: its smoother is skipped
    smoothed, filtered = data.estimates["ss_rts"], data.estimates["ss"]
    assert smoothed.labels == LABELS and np.array_equal(smoothed.steps, filtered.steps)
    np.testing.assert_array_equal(smoothed.x[-1], filtered.x[-1])
    err_s = np.sqrt(np.mean((smoothed.x - truth) ** 2, axis=0))
    err_f = np.sqrt(np.mean((filtered.x - truth) ** 2, axis=0))
    assert np.all(err_s < err_f), (err_s, err_f)
    # the smoothed covariance is consistent with its errors (NEES averaged over the run near 6)
    d = smoothed.x - truth
    nees = np.einsum("ki,kij,kj->k", d, np.linalg.inv(smoothed.P), d)
    assert 4.0 < nees.mean() < 8.0
