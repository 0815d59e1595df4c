"""NaN/inf and out-of-order measurements, replayed through the graph, are rejected with a warning and never
corrupt a filter."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from graph_helpers import SHORT_PASS, read_bag, script
from rclpy.serialization import deserialize_message, serialize_message

from bench_engine.bag_reader import BagReader
from bench_engine.bag_writer import BagWriter
from bench_msgs.msg import RangeAzEl

NAN_STEP, INF_STEP, LATE_STEP = 50, 51, 60


def _doctored_copy(bag: Path, out: Path) -> None:
    """Copy a bag, corrupting three measurements: NaN range, inf elevation, a stamp from the past."""
    reader = BagReader(bag)
    with BagWriter(out) as writer:
        for topic, type_name in reader.topics().items():
            writer.add_topic(topic, type_name)
        for topic, _type, t, data in reader.messages():
            if topic == "/radar/measurement":
                msg = deserialize_message(data, RangeAzEl)
                if msg.step == NAN_STEP:
                    msg.range = float("nan")
                elif msg.step == INF_STEP:
                    msg.elevation = float("inf")
                elif msg.step == LATE_STEP:
                    msg.header.stamp.sec -= 3
                data = serialize_message(msg)
            writer.write(topic, data, t)
    shutil.copy(bag / "run_config.yaml", out / "run_config.yaml")


def test_bad_measurements_are_rejected_and_filters_stay_sane(tmp_path: Path) -> None:
    original = tmp_path / "orig"
    res = script(
        "launch.py",
        "leo_radar",
        "--out",
        str(original),
        "--no-score",
        "--set",
        "sensors.radar.p_detect=1.0",
        *SHORT_PASS,
    )
    assert res.returncode == 0, res.stderr[-2000:]
    doctored = tmp_path / "doctored"
    _doctored_copy(original / "bag", doctored)
    replay = tmp_path / "replay"
    res = script("replay.py", str(doctored), "--estimators", "ekf,ukf", "--out", str(replay))
    assert res.returncode == 0, res.stderr[-2000:]
    before, after = read_bag(original / "bag"), read_bag(replay / "bag")
    for name in ("ekf", "ukf"):
        log = (replay / "logs" / f"{name}.log").read_text()
        for step in (NAN_STEP, INF_STEP):
            assert f"rejected measurement at step {step}: non-finite measurement" in log
        assert f"rejected measurement at step {LATE_STEP}: out-of-order measurement" in log
        est = {m.step: m for _, m in after[f"/{name}/estimate"]}
        assert not {NAN_STEP, INF_STEP, LATE_STEP} & set(est)
        assert all(np.all(np.isfinite(m.state)) and np.all(np.isfinite(m.covariance)) for m in est.values())
        # up to the first bad measurement the replay equals the original run exactly
        orig = {m.step: m for _, m in before[f"/{name}/estimate"]}
        np.testing.assert_array_equal(est[NAN_STEP - 1].state, orig[NAN_STEP - 1].state)
        # afterwards, skipping three scans only perturbs the estimate slightly
        last = max(est)
        truth = {m.step: m for _, m in after["/truth/state"]}[last]
        err_replay = np.linalg.norm(np.array(est[last].state[:3]) - truth.state[:3])
        err_orig = np.linalg.norm(np.array(orig[last].state[:3]) - truth.state[:3])
        assert err_replay < 2.0 * err_orig + 100.0
