"""grace_velocity (paper 002) through the ROS 2 graph, headless: two hours of the day (1 441 steps of 5 s) with
the filters on the baseline (a, b) and on each satellite, read back with rosbags and scored.

Checks the bag's topics, counts and stamps, that the derived measurements are what their definitions say
(difference of the two receivers' fixes; Newton velocities half a window late), that the graph carries what
the same cores give in process, and two known answers of the scorer: the KBR residual of the truth is the KBR
noise, and Newton's range-rate error is the GNSS noise propagated through its weights.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from graph_helpers import read_bag, script, stamp

from bench_engine.config import apply_overrides, load_scenario, select_variant
from bench_engine.inprocess import run_in_process
from bench_engine.views import SUFFIXES

STEPS = 1441
SIGMA_GNSS = 0.02
WINDOW = ["scoring.window.head_s=600", "scoring.window.tail_s=600"]  # the scenario's hour-long margins: 10 min
ARGS = [
    "--set",
    "time.duration=7200",
    *(a for w in WINDOW for a in ("--set", w)),
    "--variant",
    "satellites",
    "--seed",
    "3",
]
PAIR = [
    "x1",
    "y1",
    "z1",
    "vx1",
    "vy1",
    "vz1",
    "x2",
    "y2",
    "z2",
    "vx2",
    "vy2",
    "vz2",
    "bx",
    "by",
    "bz",
    "bvx",
    "bvy",
    "bvz",
]


@pytest.fixture(scope="module")
def graph_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("grace") / "run"
    res = script("launch.py", "grace_velocity", "--out", str(out), "--json", *ARGS, timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    return out, read_bag(out / "bag"), json.loads(res.stdout)


def msgs(bag: dict, topic: str) -> list:
    return [m for _, m in bag[topic]]


def test_every_topic_is_recorded_at_its_rate(graph_run) -> None:
    _, bag, _ = graph_run
    assert {t for t in bag if t.rsplit("/", 1)[1] not in SUFFIXES} == {  # beside the standard views
        "/clock",
        "/truth/state",
        "/gnss1/measurement",
        "/gnss2/measurement",
        "/kbr/measurement",
        "/baseline/measurement",
        "/baseline_pv/measurement",
        "/kf_a/estimate",
        "/kf_b/estimate",
        "/kf_sat1/estimate",
        "/kf_sat2/estimate",
        "/kf_a_lag/estimate",
    }
    truth = msgs(bag, "/truth/state")
    assert [m.step for m in truth] == list(range(STEPS))
    assert list(truth[0].labels) == PAIR and truth[0].header.frame_id == "eci"
    assert [m.step for m in msgs(bag, "/kbr/measurement")] == list(range(STEPS))
    fixes = list(range(0, STEPS, 2))  # GNSS every 10 s
    for topic in ("/gnss1/measurement", "/gnss2/measurement", "/baseline/measurement"):
        assert [m.step for m in msgs(bag, topic)] == fixes
    assert [m.step for m in msgs(bag, "/baseline_pv/measurement")] == fixes[2:-2]  # centred 5-point window
    for name, labels in (("kf_a", "b"), ("kf_sat1", "1")):
        est = msgs(bag, f"/{name}/estimate")
        assert [e.step for e in est] == fixes and all(e.header.frame_id == "eci" for e in est)
        assert list(est[0].labels)[:3] == (["bx", "by", "bz"] if labels == "b" else ["x1", "y1", "z1"])


def test_derived_measurements_follow_their_definitions(graph_run) -> None:
    _, bag, _ = graph_run
    g1 = {m.step: np.asarray(m.value) for m in msgs(bag, "/gnss1/measurement")}
    g2 = {m.step: np.asarray(m.value) for m in msgs(bag, "/gnss2/measurement")}
    for m in msgs(bag, "/baseline/measurement"):
        np.testing.assert_array_equal(m.value, g2[m.step] - g1[m.step])
        np.testing.assert_allclose(np.reshape(m.covariance, (3, 3)), 2 * SIGMA_GNSS**2 * np.eye(3), rtol=1e-12)
    base = {m.step: np.asarray(m.value) for m in msgs(bag, "/baseline/measurement")}
    for m in msgs(bag, "/baseline_pv/measurement"):
        assert list(m.labels) == ["bx", "by", "bz", "bvx", "bvy", "bvz"]
        np.testing.assert_array_equal(m.value[:3], base[m.step])
        assert stamp(m) == pytest.approx(5.0 * m.step)


def test_the_graph_carries_what_the_cores_give_in_process(graph_run) -> None:
    _, bag, _ = graph_run
    cfg = apply_overrides(
        select_variant(load_scenario("grace_velocity"), "satellites"), ["time.duration=7200", *WINDOW]
    )
    run = run_in_process(cfg, ["kf_a", "kf_b"], seed=3)
    for name in ("kf_a", "kf_b"):
        graph = msgs(bag, f"/{name}/estimate")
        local = run.items[f"/{name}/estimate"]
        assert len(graph) == len(local)
        np.testing.assert_array_equal(np.array([m.state for m in graph]), np.array([e.x for e in local]))


def test_the_fixed_lag_smoother_runs_in_the_graph_300_s_behind(graph_run) -> None:
    _, bag, scored = graph_run
    lag = msgs(bag, "/kf_a_lag/estimate")
    fixes = list(range(0, STEPS, 2))
    assert [e.step for e in lag] == fixes[:-30]  # 300 s = 30 fixes at 10 s
    scores = scored["estimators"]
    # the in-graph smoother sees 300 s of future data: close to the offline RTS over the whole run
    assert scores["kf_a_lag"]["rr_truth"]["std"] < 0.6 * scores["kf_a"]["rr_truth"]["std"]


def test_scores_have_their_known_answers(graph_run) -> None:
    _, _, scored = graph_run
    scores = scored["estimators"]
    assert {"kf_a", "kf_b", "kf_a_rts", "kf_a_lag", "newton", "savgol", "kf_pair"} <= set(scores)
    floor = scores["kf_a"]["kbr_noise_std"]
    assert floor == pytest.approx(1e-6, rel=0.1)  # the KBR's sigma
    # Newton's 5-point centred derivative: weights (1, -8, 0, 8, -1) / (12 h), h = 10 s, on a baseline of
    # noise sqrt(2) sigma per axis; the range rate sees the along-baseline component only
    expected = np.sqrt(2) * SIGMA_GNSS * np.sqrt(130.0) / 120.0
    assert scores["newton"]["rr_truth"]["std"] == pytest.approx(expected, rel=0.1)
    for block in scores.values():
        assert abs(block["rr_kbr"]["std"] - block["rr_truth"]["std"]) < 0.05 * block["rr_truth"]["std"] + 2e-6
    # the filters on each satellite see the same fixes as kf_a's baseline: their difference is no better
    assert scores["kf_pair"]["rr_truth"]["std"] > 0.5 * scores["kf_a"]["rr_truth"]["std"]


def test_outages_and_gross_outliers_give_a_well_defined_run(tmp_path) -> None:
    """Variant faults: receiver 1 is out for 10 minutes and 1 % of fixes carry a 30 m error. The run completes,
    the filters gate the outliers (logged), bridge the outage and resume, and every score stays finite."""
    out = tmp_path / "faults"
    res = script(
        "launch.py",
        "grace_velocity",
        "--out",
        str(out),
        "--json",
        "--variant",
        "faults",
        "--set",
        "time.duration=3600",
        *(a for w in WINDOW for a in ("--set", w)),
        "--set",
        "sensors.gnss1.outages=[[1800.0, 2400.0]]",
        timeout=600,
    )  # the variant's: in its scored day
    assert res.returncode == 0, res.stderr[-3000:]
    bag = read_bag(out / "bag")
    g1 = [m.step for m in msgs(bag, "/gnss1/measurement")]
    assert not [k for k in g1 if 1800.0 <= 5.0 * k <= 2400.0] and len(g1) == 361 - 61
    kf_a = [e.step for e in msgs(bag, "/kf_a/estimate")]
    assert max(kf_a) == 720 and any(5.0 * k > 2400.0 for k in kf_a)
    log = (out / "logs" / "kf_a.log").read_text()
    gated = {int(k) for k in re.findall(r"at step (\d+): gated outlier", log)}
    outliers = {
        m.step
        for m in msgs(bag, "/baseline/measurement")
        if np.max(np.abs(np.asarray(m.value) - _true_baseline(bag, m.step))) > 1.0
    }
    assert outliers - {0} and outliers - {0} <= gated  # every gross outlier is gated ...
    after_outage = sorted(gated - outliers)  # ... and the others follow the 10-minute gap:
    assert all(482 <= k <= 490 for k in after_outage), (after_outage, sorted(outliers))  # lock lost across it,
    if after_outage:  # so the filter restarts and says so
        assert "lost lock and restarts" in log
    for name, block in json.loads(res.stdout)["estimators"].items():
        assert np.isfinite(block["rr_kbr"]["std"]), name
    last = msgs(bag, "/kf_a/estimate")[-1]  # converged again by the end of the hour
    truth = msgs(bag, "/truth/state")[last.step]
    v_true = np.asarray(truth.state)[[list(truth.labels).index(c) for c in ("bvx", "bvy", "bvz")]]
    assert np.linalg.norm(np.asarray(last.state)[3:6] - v_true) < 0.05


def _true_baseline(bag: dict, step: int) -> np.ndarray:
    truth = msgs(bag, "/truth/state")[step]
    labels = list(truth.labels)
    return np.asarray(truth.state)[[labels.index(c) for c in ("bx", "by", "bz")]]
