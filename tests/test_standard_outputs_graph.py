"""The standard views (bench_engine.views) through the graph: short leo_radar and star_tracker runs launched as a
user would, their bags read back with rosbags (an independent reader), every view message checked against the
StateEstimate or TruthState it views (same stamp, frame, values, covariance blocks; one Odometry and pose per
estimate, diagnostics and markers once per second of sim time); the
recorder closes the bag with them, the scorer ignores them, and a Monte Carlo batch makes its runs without."""

from __future__ import annotations

import math
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import yaml
from graph_helpers import read_bag, script, stamp
from scipy.spatial.transform import Rotation

from bench_engine import views
from bench_engine.batch import RunSpec, reusable_run
from bench_engine.config import ScenarioError


def counts(bag_dir: Path) -> dict[str, int]:
    info = yaml.safe_load((bag_dir / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    return {t["topic_metadata"]["name"]: t["message_count"] for t in info["topics_with_message_count"]}


def at(labels, names) -> list[int]:
    labels = list(labels)
    return [labels.index(n) for n in names]


def periodic_steps(stamps_ns: list[int], period_s: float) -> list[int]:
    """Which items get a periodic view (a trajectory marker, a diagnostics status): the first, then each one
    ``period_s`` after the last one that got it."""
    marked, last = [], None
    for i, t in enumerate(stamps_ns):
        if last is None or t - last >= period_s * 1e9:
            marked.append(i)
            last = t
    return marked


def ns(msg) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def check_markers(bag: dict, node: str, items: list) -> None:
    markers = [m for _, m in bag[f"/{node}/markers"]]
    expected = periodic_steps([ns(m) for m in items], views.MARKER_PERIOD_S)
    assert len(markers) == len(expected)
    ids = [m.id for m in markers]
    assert ids == list(range(len(markers)))
    for i, marker in zip(expected, markers):
        item = items[i]
        end = marker.points[-1]
        x = np.asarray(item.state)[at(item.labels, "xyz")]
        assert [end.x, end.y, end.z] == x.tolist()
        assert marker.ns == node and marker.header.frame_id == item.header.frame_id and ns(marker) == ns(item)
        assert (marker.lifetime.sec, marker.lifetime.nanosec) == (0, 0) and marker.type == 4


def test_leo_radar_publishes_odometry_diagnostics_and_markers_beside_its_estimates(tmp_path):
    out = tmp_path / "run"
    res = script("launch.py", "leo_radar", "--set", "time.duration=30", "--out", str(out), timeout=240)
    assert res.returncode == 0, res.stdout + res.stderr
    assert "ukf:" in res.stdout and "ekf:" in res.stdout  # scored as before: the scorer ignores the views
    n = counts(out / "bag")
    bag = read_bag(out / "bag")
    for node in ("ekf", "ukf"):
        estimates = [m for _, m in bag[f"/{node}/estimate"]]
        assert len(estimates) > 250
        assert n[f"/{node}/odometry"] == n[f"/{node}/estimate"] == len(estimates)
        assert f"/{node}/pose" not in n and f"/{node}/attitude" not in n  # an orbit state has no attitude
        odometry = [m for _, m in bag[f"/{node}/odometry"]]
        for est, odo in zip(estimates, odometry):
            assert ns(odo) == ns(est)
            assert (odo.header.frame_id, odo.child_frame_id) == ("eci", node)
            x, P = np.asarray(est.state), np.reshape(est.covariance, (6, 6))
            pos, vel = at(est.labels, "xyz"), at(est.labels, ("vx", "vy", "vz"))
            p, v = odo.pose.pose.position, odo.twist.twist.linear
            assert [p.x, p.y, p.z] == x[pos].tolist() and [v.x, v.y, v.z] == x[vel].tolist()
            pose, twist = np.reshape(odo.pose.covariance, (6, 6)), np.reshape(odo.twist.covariance, (6, 6))
            assert (pose[:3, :3] == P[np.ix_(pos, pos)]).all() and (twist[:3, :3] == P[np.ix_(vel, vel)]).all()
            assert np.diag(pose)[3:].tolist() == [views.UNKNOWN_VARIANCE] * 3
        # diagnostics about once a second (ROS's convention), each the status of the estimates since the last
        diagnostics = [m for _, m in bag[f"/{node}/diagnostics"]]
        stamped = periodic_steps([ns(m) for m in estimates], views.DIAGNOSTICS_PERIOD_S)
        assert len(diagnostics) == len(stamped) and 25 <= len(diagnostics) <= 32
        for previous, i, diag in zip([-1, *stamped], stamped, diagnostics):
            est, window = estimates[i], estimates[previous + 1 : i + 1]
            assert ns(diag) == ns(est)
            (status,) = diag.status
            values = {kv.key: kv.value for kv in status.values}
            assert status.name == node and int(values["step"]) == est.step
            nis = float(values["nis"])
            assert nis == est.nis or (math.isnan(nis) and math.isnan(est.nis))
            coasted = sum(math.isnan(e.nis) for e in window)
            assert (int(values.pop("window_estimates")), int(values.pop("window_without_update"))) == (
                len(window),
                coasted,
            )
            assert status.level == (1 if coasted else 0)  # WARN, OK (rosbags reads a byte as an int)
            assert dict(zip(est.diagnostic_names, est.diagnostic_values)) == {
                k: float(v) for k, v in values.items() if k not in ("step", "nis")
            }
        check_markers(bag, node, estimates)
    truth = [m for _, m in bag["/truth/state"]]
    assert n["/truth/odometry"] == n["/truth/state"] == 301 and "/truth/pose" not in n
    for state, odo in zip(truth, (m for _, m in bag["/truth/odometry"])):
        p = odo.pose.pose.position
        assert ns(odo) == ns(state) and odo.child_frame_id == "truth"
        assert [p.x, p.y, p.z] == np.asarray(state.state)[at(state.labels, "xyz")].tolist()
        assert not np.reshape(odo.pose.covariance, (6, 6))[:3, :3].any()  # exact
    check_markers(bag, "truth", truth)


def test_star_tracker_attitudes_are_poses_and_attitude_estimates(tmp_path):
    out = tmp_path / "run"
    res = script(
        "launch.py",
        "star_tracker",
        "--variant",
        "short",
        "--estimators",
        "sna_triad,jpdaf_wahba",
        "--out",
        str(out),
        "--no-score",
        timeout=240,
    )
    assert res.returncode == 0, res.stdout + res.stderr
    n = counts(out / "bag")
    bag = read_bag(out / "bag")
    for node in ("sna_triad", "jpdaf_wahba"):
        estimates = [m for _, m in bag[f"/{node}/estimate"]]
        assert len(estimates) >= 90
        assert n[f"/{node}/pose"] == n[f"/{node}/attitude"] == len(estimates)
        assert n[f"/{node}/diagnostics"] == len(
            periodic_steps([ns(m) for _, m in bag[f"/{node}/estimate"]], views.DIAGNOSTICS_PERIOD_S)
        )
        assert f"/{node}/odometry" not in n and f"/{node}/markers" not in n  # no position
        poses = [m for _, m in bag[f"/{node}/pose"]]
        attitudes = [m for _, m in bag[f"/{node}/attitude"]]
        for est, pose, att in zip(estimates, poses, attitudes):
            assert ns(pose) == ns(est) == ns(att) and pose.header.frame_id == att.header.frame_id == "icrs"
            q = np.asarray(est.state)[at(est.labels, ("qw", "qx", "qy", "qz"))]
            P = np.reshape(est.covariance, (3, 3))
            o = att.orientation
            assert [o.w, o.x, o.y, o.z] == q.tolist() and np.reshape(att.covariance, (3, 3)).tolist() == P.tolist()
            stars = dict(zip(est.diagnostic_names, est.diagnostic_values))["stars"]
            assert att.stars_used == int(stars) and att.estimator_name == node and att.step == est.step
            A = Rotation.from_quat(q, scalar_first=True).as_matrix()  # camera from ICRS
            o = pose.pose.pose.orientation
            np.testing.assert_allclose(Rotation.from_quat([o.x, o.y, o.z, o.w]).as_matrix(), A.T, atol=1e-12)
            cov = np.reshape(pose.pose.covariance, (6, 6))
            np.testing.assert_allclose(cov[3:, 3:], A.T @ P @ A, rtol=1e-9, atol=1e-30)
    assert n["/truth/pose"] == n["/truth/state"] == 100 and "/truth/odometry" not in n
    truth_pose = bag["/truth/pose"][0][1]
    assert truth_pose.header.frame_id == "icrs" and stamp(truth_pose) == stamp(bag["/truth/state"][0][1])


def test_a_batch_makes_its_runs_without_views(tmp_path):
    spec = RunSpec("leo_radar", tmp_path / "run_000", 1, overrides=["time.duration=5"])
    assert " ".join(spec.command(None)).endswith(f"--set {views.SWITCH}=false --set time.duration=5")
    on = RunSpec("leo_radar", tmp_path / "x", 1, overrides=[f"{views.SWITCH}=true"])
    assert f"{views.SWITCH}=false" not in on.command(None)
    assert f"{views.SWITCH}=false" not in RunSpec("leo_radar", tmp_path / "y", 1, standard_views=True).command(None)
    # a batch's run is resumed although its bag records the switch its caller did not set
    bag = tmp_path / "run_000" / "bag"
    bag.mkdir(parents=True)
    (bag / "metadata.yaml").write_text(
        yaml.safe_dump(
            {
                "rosbag2_bagfile_information": {
                    "topics_with_message_count": [{"topic_metadata": {"name": "/truth/state"}, "message_count": 51}]
                }
            }
        )
    )
    scenario = {"scenario": "leo_radar", "time": {"start": 4320.8, "duration": 5.0, "dt": 0.1}, "seed": 1}
    (bag / "run_config.yaml").write_text(yaml.safe_dump({"scenario": {**scenario, views.SWITCH: False}}))
    assert reusable_run(tmp_path / "run_000", scenario, resume=True)
    with pytest.raises(ScenarioError, match="another configuration"):
        reusable_run(tmp_path / "run_000", {**scenario, "seed": 2}, resume=True)


def test_the_switch_turns_the_views_off(tmp_path):
    out = tmp_path / "run"
    res = script(
        "launch.py",
        "leo_radar",
        "--set",
        "time.duration=5",
        "--set",
        "standard_views=false",
        "--estimators",
        "ukf",
        "--out",
        str(out),
        "--no-score",
        "--single-process",
        timeout=240,
    )
    assert res.returncode == 0, res.stdout + res.stderr
    assert Counter(t.rsplit("/", 1)[1] for t in counts(out / "bag")) == Counter(
        {"state": 1, "clock": 1, "measurement": 1, "estimate": 1}
    )
