"""The standard views of estimates and truth (bench_engine.views), as pure conversions: components selected by
label, covariance blocks placed right, frames named, no Odometry for a state without velocity, attitudes as ROS
poses, diagnostics read back exactly and periodic, trajectory markers cheap and cumulative, the Odometry encoder's
bytes the serialiser's; and the graph's view topics."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.serialization import deserialize_message
from scipy.spatial.transform import Rotation

from bench_engine import cdr, view_state, views
from bench_engine.config import ScenarioError, load_scenario
from bench_engine.graph import NodeSpec, build_graph
from bench_engine.msg_schema import message_class
from bench_engine.stage import Estimate, TruthSample
from bench_models.states import error_labels


def spd(n: int, seed: int) -> np.ndarray:
    a = np.random.default_rng(seed).normal(size=(n, n))
    return a @ a.T + n * np.eye(n)


def estimate(labels, x, P, t_ns=12_300_000_000, nis=2.5, diagnostics=None, frame="eci", source="ukf", step=7):
    return Estimate(
        step,
        t_ns,
        frame,
        source,
        list(labels),
        np.asarray(x, float),
        np.asarray(P, float),
        nis,
        dict(diagnostics or {}),
    )


def read_back(type_name: str, msg):
    """The message as rclpy reads the bytes the node would publish."""
    return deserialize_message(cdr.serialize(type_name, msg), message_class(type_name))


# --- graph ------------------------------------------------------------------------------------------------


def test_view_topics_follow_the_topic_contract():
    assert views.view_topics("/ukf/estimate", "bench_msgs/msg/StateEstimate") == {
        "/ukf/odometry": "nav_msgs/msg/Odometry",
        "/ukf/pose": "geometry_msgs/msg/PoseWithCovarianceStamped",
        "/ukf/attitude": "bench_msgs/msg/AttitudeEstimate",
        "/ukf/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
        "/ukf/markers": "visualization_msgs/msg/Marker",
    }
    assert views.view_topics("/truth/state", "bench_msgs/msg/TruthState") == {
        "/truth/odometry": "nav_msgs/msg/Odometry",
        "/truth/pose": "geometry_msgs/msg/PoseWithCovarianceStamped",
        "/truth/markers": "visualization_msgs/msg/Marker",
    }
    orbit, attitude = ("x", "y", "z", "vx", "vy", "vz"), ("qw", "qx", "qy", "qz")
    assert sorted(views.view_topics("/ukf/estimate", "bench_msgs/msg/StateEstimate", orbit)) == [
        "/ukf/diagnostics",
        "/ukf/markers",
        "/ukf/odometry",
    ]  # no attitude in an orbit state
    assert sorted(views.view_topics("/st/estimate", "bench_msgs/msg/StateEstimate", attitude)) == [
        "/st/attitude",
        "/st/diagnostics",
        "/st/pose",
    ]  # no position in an attitude
    assert sorted(views.view_topics("/truth/state", "bench_msgs/msg/TruthState", ("x", "y", "z"))) == ["/truth/markers"]
    assert views.view_topics("/truth/state", "bench_msgs/msg/TruthState", ("x1", "bx")) == {}
    for topic, type_name in (
        ("/radar/measurement", "bench_msgs/msg/RangeAzEl"),
        ("/clock", "rosgraph_msgs/msg/Clock"),
        ("/ukf/stars", "bench_msgs/msg/StarCentroids"),
        ("/ukf/estimate", "bench_msgs/msg/TruthState"),
        ("/a/b/estimate", "bench_msgs/msg/StateEstimate"),
    ):
        assert views.view_topics(topic, type_name) == {}


def test_add_standard_views_adds_each_publisher_its_views():
    truth = NodeSpec(
        "truth", "truth", publishes={"/truth/state": "bench_msgs/msg/TruthState", "/clock": "rosgraph_msgs/msg/Clock"}
    )
    radar = NodeSpec("radar", "sensor", publishes={"/radar/measurement": "bench_msgs/msg/RangeAzEl"})
    ukf = NodeSpec("ukf", "filter", publishes={"/ukf/estimate": "bench_msgs/msg/StateEstimate"})
    views.add_standard_views([truth, radar, ukf], {"standard_views": False})
    assert list(ukf.publishes) == ["/ukf/estimate"] and len(truth.publishes) == 2
    views.add_standard_views([truth, radar, ukf], {})
    assert sorted(truth.publishes) == ["/clock", "/truth/markers", "/truth/odometry", "/truth/pose", "/truth/state"]
    assert list(radar.publishes) == ["/radar/measurement"]
    assert sorted(ukf.publishes) == sorted(["/ukf/estimate"] + [f"/ukf/{s}" for s in views.SUFFIXES])
    kf = NodeSpec(
        "kf",
        "filter",
        publishes={"/kf/estimate": "bench_msgs/msg/StateEstimate"},
        labels={"/kf/estimate": ("bx", "by", "bz")},
    )
    views.add_standard_views([kf], {})
    assert sorted(kf.publishes) == ["/kf/diagnostics", "/kf/estimate"]


@pytest.mark.parametrize(
    "scenario, node, advertised",
    [
        ("leo_radar", "ukf", ["diagnostics", "estimate", "markers", "odometry"]),
        ("leo_radar", "truth", ["clock", "markers", "odometry", "state"]),
        ("star_tracker", "jpdaf_wahba", ["attitude", "diagnostics", "estimate", "pose", "stars"]),
        ("star_tracker", "truth", ["clock", "pose", "state"]),
        ("grace_velocity", "kf_a", ["diagnostics", "estimate"]),
        ("grace_velocity", "kf_a_lag", ["diagnostics", "estimate"]),
        ("grace_velocity", "truth", ["clock", "state"]),
        ("formation_cqkf", "cwb", ["diagnostics", "estimate", "markers", "odometry"]),
        (
            str(Path(__file__).parent / "data" / "tracker_formation.yaml"),
            "gnn",
            ["diagnostics", "estimate", "markers", "odometry"],
        ),
    ],
)
def test_a_node_advertises_only_the_views_its_state_supports(scenario: str, node: str, advertised: list) -> None:
    """The graph gives each estimate and truth topic the views its state's labels support (a leo_radar UKF's
    orbit state has no attitude: no /ukf/pose, no /ukf/attitude), from the kinds' settings alone."""
    graph = build_graph(load_scenario(scenario), None)
    assert sorted(t.rsplit("/", 1)[1] for t in graph.node(node).publishes) == advertised


def test_the_switch_is_a_bool():
    assert views.standard_views({}) and not views.standard_views({"standard_views": False})
    with pytest.raises(ScenarioError, match="standard_views"):
        views.standard_views({"standard_views": "no"})


def test_the_views_module_imports_no_rclpy():
    code = "import sys, bench_engine.views; sys.exit('rclpy' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0


# --- Odometry ---------------------------------------------------------------------------------------------


@settings(max_examples=40, deadline=None)
@given(st.permutations(["x", "y", "z", "vx", "vy", "vz", "bx", "ax"]), st.integers(0, 10_000))
def test_odometry_selects_by_label_and_places_the_covariance_blocks(labels, seed):
    n = len(labels)
    x = np.random.default_rng(seed).normal(size=n) * 1e6
    P = spd(n, seed)
    msg = read_back(views.ODOMETRY_TYPE, views.odometry(estimate(labels, x, P), "ukf"))
    at = {lab: i for i, lab in enumerate(labels)}
    pos, vel = [at[c] for c in "xyz"], [at[c] for c in ("vx", "vy", "vz")]
    p, v = msg.pose.pose.position, msg.twist.twist.linear
    assert [p.x, p.y, p.z] == x[pos].tolist() and [v.x, v.y, v.z] == x[vel].tolist()
    pose, twist = np.reshape(msg.pose.covariance, (6, 6)), np.reshape(msg.twist.covariance, (6, 6))
    np.testing.assert_array_equal(pose[:3, :3], P[np.ix_(pos, pos)])
    np.testing.assert_array_equal(twist[:3, :3], P[np.ix_(vel, vel)])
    for block in (pose, twist):
        assert np.diag(block)[3:].tolist() == [views.UNKNOWN_VARIANCE] * 3
        assert not block[:3, 3:].any() and not block[3:, :3].any()
        assert not (block[3:, 3:] - np.diag(np.diag(block[3:, 3:]))).any()
    o = msg.pose.pose.orientation
    assert (o.x, o.y, o.z, o.w) == (0.0, 0.0, 0.0, 1.0)
    assert (msg.header.frame_id, msg.child_frame_id) == ("eci", "ukf")
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (12, 300_000_000)


@settings(max_examples=40, deadline=None)
@given(
    st.permutations(["x", "y", "z", "vx", "vy", "vz", "bx", "ax"]),
    st.integers(0, 10_000),
    st.sampled_from(["eci", "lvlh", "a_longer_frame_name"]),
    st.sampled_from(["ukf", "kf_a_q", "truth"]),
    st.integers(0, 2**40),
    st.booleans(),
)
def test_the_odometry_encoder_writes_the_serialisers_bytes(labels, seed, frame, child, t_ns, is_truth):
    """OdometryEncoder skips the message objects and rosbags' serialiser: its bytes must be theirs exactly (CDR
    layout and alignment, stamp, frame names of any length, every number), for estimates and the truth."""
    n = len(labels)
    x = np.random.default_rng(seed).normal(size=n) * 1e6
    item = (
        TruthSample(4, t_ns, frame, list(labels), x)
        if is_truth
        else estimate(labels, x, spd(n, seed), t_ns=t_ns, frame=frame)
    )
    encoder = views.OdometryEncoder(child)
    expected = cdr.serialize(views.ODOMETRY_TYPE, views.odometry(item, child))
    assert encoder(item) == expected
    assert encoder(item) == expected  # its cached prefix too
    assert views.OdometryEncoder(child)(estimate(["x", "y", "z"], [1, 2, 3], np.eye(3))) is None


def test_no_odometry_without_velocity_or_position():
    assert views.odometry(estimate(["x", "y", "z"], [1, 2, 3], np.eye(3)), "ukf") is None
    assert views.odometry(estimate(["vx", "vy", "vz"], [1, 2, 3], np.eye(3)), "ukf") is None
    assert views.odometry(estimate(["x1", "y1", "z1", "vx1", "vy1", "vz1"], np.ones(6), np.eye(6)), "kf") is None
    grace = TruthSample(0, 0, "eci", ["x1", "y1", "z1", "vx1", "vy1", "vz1"], np.ones(6))
    assert views.odometry(grace, "truth") is None


def test_truth_odometry_is_exact_where_known():
    truth = TruthSample(3, 5_000_000_000, "lvlh", ["x", "y", "z", "vx", "vy", "vz"], np.arange(6.0))
    msg = read_back(views.ODOMETRY_TYPE, views.odometry(truth, "truth"))
    assert msg.header.frame_id == "lvlh" and msg.child_frame_id == "truth"
    assert msg.pose.pose.position.z == 2.0 and msg.twist.twist.linear.x == 3.0
    for cov in (msg.pose.covariance, msg.twist.covariance):
        assert np.diag(np.reshape(cov, (6, 6))).tolist() == [0.0] * 3 + [views.UNKNOWN_VARIANCE] * 3


# --- attitude ---------------------------------------------------------------------------------------------


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000), st.booleans())
def test_an_attitude_is_the_pose_of_the_body_with_its_error_covariance_in_the_reference_frame(seed, scalar_negative):
    rng = np.random.default_rng(seed)
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    q *= -1 if scalar_negative else 1
    labels = ["qw", "qx", "qy", "qz", "bx"]
    P = spd(4, seed)  # over the error labels rx ry rz bx
    assert error_labels(labels) == ["rx", "ry", "rz", "bx"] == list(view_state.covariance_labels(tuple(labels), 4))
    item = estimate(labels, [*q, 0.5], P, frame="icrs", source="sna_triad", diagnostics={"stars": 12.0})
    msg = read_back(views.POSE_TYPE, views.pose(item))
    A = Rotation.from_quat(q, scalar_first=True).as_matrix()  # camera-from-ICRS (star_tracker.attitude)
    o = msg.pose.pose.orientation
    body_in_reference = Rotation.from_quat([o.x, o.y, o.z, o.w]).as_matrix()
    np.testing.assert_allclose(body_in_reference, A.T, atol=1e-12)  # takes camera coordinates to ICRS ones
    cov = np.reshape(msg.pose.covariance, (6, 6))
    np.testing.assert_allclose(cov[3:, 3:], A.T @ P[:3, :3] @ A, rtol=1e-12, atol=1e-12)
    assert np.diag(cov)[:3].tolist() == [views.UNKNOWN_VARIANCE] * 3 and not cov[:3, 3:].any()
    assert msg.header.frame_id == "icrs"
    att = read_back(views.ATTITUDE_TYPE, views.attitude(item))
    o = att.orientation
    assert [o.w, o.x, o.y, o.z] == q.tolist()  # the estimate's own convention
    np.testing.assert_array_equal(np.reshape(att.covariance, (3, 3)), P[:3, :3])
    assert (att.estimator_name, att.stars_used, att.step, att.header.frame_id) == ("sna_triad", 12, 7, "icrs")
    item.diagnostics["stars"] = float("nan")
    assert views.attitude(item).stars_used == 0


def test_a_pose_with_position_and_attitude_carries_the_cross_covariance():
    labels = ["x", "y", "z", "qw", "qx", "qy", "qz"]
    q = np.array([0.5, 0.5, -0.5, 0.5])
    P = spd(6, 3)  # x y z rx ry rz
    msg = views.pose(estimate(labels, [1.0, 2.0, 3.0, *q], P))
    cov = np.reshape(msg.pose.covariance, (6, 6))
    A = Rotation.from_quat(q, scalar_first=True).as_matrix()
    np.testing.assert_array_equal(cov[:3, :3], P[:3, :3])
    np.testing.assert_allclose(cov[:3, 3:], P[:3, 3:] @ A, atol=1e-12)
    np.testing.assert_allclose(cov, cov.T, atol=1e-12)
    assert msg.pose.pose.position.y == 2.0


def test_attitude_truth_has_a_pose_and_no_estimate_views():
    truth = TruthSample(
        2, 200_000_000, "icrs", ["qw", "qx", "qy", "qz", "wx", "wy", "wz"], np.array([1.0, 0, 0, 0, 0.1, 0.2, 0.3])
    )
    msg = views.pose(truth)
    assert msg.pose.pose.orientation.w == 1.0 and not np.reshape(msg.pose.covariance, (6, 6))[3:, 3:].any()
    assert views.attitude(truth) is None and views.diagnostics(truth) is None and views.odometry(truth, "t") is None
    assert views.pose(estimate(["x", "y", "z", "vx", "vy", "vz"], np.ones(6), np.eye(6))) is None


# --- diagnostics ------------------------------------------------------------------------------------------


def test_diagnostics_read_back_exactly():
    item = estimate(["x"], [1.0], [[1.0]], nis=0.1 + 0.2, diagnostics={"n_eff": 1234.5678, "gated": 1.0})
    msg = read_back(views.DIAGNOSTICS_TYPE, views.diagnostics(item))
    (status,) = msg.status
    values = {kv.key: kv.value for kv in status.values}
    assert status.name == "ukf" and status.level == b"\x00"  # OK
    assert float(values["nis"]) == 0.1 + 0.2 and float(values["n_eff"]) == 1234.5678 and values["step"] == "7"
    assert list(values) == ["step", "nis", "n_eff", "gated", "window_estimates", "window_without_update"]
    assert (values["window_estimates"], values["window_without_update"]) == ("1", "0")
    coasting = views.diagnostics(estimate(["x"], [1.0], [[1.0]], nis=float("nan")))
    assert coasting.status[0].level == 1 and coasting.status[0].message  # WARN: no update


def test_diagnostics_are_periodic_and_count_the_estimates_without_an_update():
    """One DiagnosticArray per DIAGNOSTICS_PERIOD_S of sim time (the first estimate gets one), the status of the
    estimates since the previous one: WARN as soon as one of them coasted, with the count."""
    diag = views.PeriodicDiagnostics(period_s=1.0)
    out = []
    for k in range(36):  # 10 Hz; steps 12..14 and 25 coast
        nis = float("nan") if k in (12, 13, 14, 25) else 1.0 + k
        msg = diag(estimate(["x"], [1.0], [[1.0]], t_ns=4_000_000_000 + k * 100_000_000, nis=nis, step=k))
        if msg is not None:
            out.append((k, read_back(views.DIAGNOSTICS_TYPE, msg)))
    assert [k for k, _ in out] == [0, 10, 20, 30]
    for k, msg in out:
        (status,) = msg.status
        values = {kv.key: kv.value for kv in status.values}
        assert int(values["step"]) == k and float(values["nis"]) == 1.0 + k
        assert values["window_estimates"] == ("1" if k == 0 else "10")
    levels = [
        (msg.status[0].level, {kv.key: kv.value for kv in msg.status[0].values}["window_without_update"])
        for _, msg in out
    ]
    assert levels == [(b"\x00", "0"), (b"\x00", "0"), (b"\x01", "3"), (b"\x01", "1")]  # OK, OK, WARN, WARN
    assert "3 of the 10 estimates" in out[2][1].status[0].message
    assert diag(TruthSample(0, 9_000_000_000, "eci", ["x"], np.ones(1))) is None


# --- markers ----------------------------------------------------------------------------------------------


def test_trajectory_markers_are_decimated_joined_segments_with_unique_ids():
    markers = views.TrajectoryMarkers("ukf", period_s=1.0)
    out = []
    for k in range(35):  # 10 Hz
        x = np.array([7e6 + k, 2.0 * k, 0.0, 1.0, 2.0, 3.0])
        msg = markers(estimate(["x", "y", "z", "vx", "vy", "vz"], x, np.eye(6), t_ns=4_000_000_000 + k * 100_000_000))
        if msg is not None:
            out.append((k, read_back(views.MARKERS_TYPE, msg)))
    assert [k for k, _ in out] == [0, 10, 20, 30]
    ids = [m.id for _, m in out]
    assert ids == [0, 1, 2, 3]
    previous = None
    for k, marker in out:
        assert (marker.ns, marker.type, marker.action) == ("ukf", 4, 0)  # LINE_STRIP, ADD
        assert (marker.lifetime.sec, marker.lifetime.nanosec) == (0, 0)  # forever
        assert marker.header.frame_id == "eci" and marker.scale.x == pytest.approx(2e-3 * 7e6)
        start, end = marker.points
        assert (end.x, end.y) == (7e6 + k, 2.0 * k)
        assert (start.x, start.y) == ((previous.x, previous.y) if previous else (end.x, end.y))
        assert marker.color.a == 1.0
        previous = end
    assert markers(estimate(["qw", "qx", "qy", "qz"], [1.0, 0, 0, 0], np.eye(3), t_ns=9e9)) is None


def test_standard_views_of_an_estimate_topic():
    sv = views.StandardViews("ekf", {s: f"/ekf/{s}" for s in views.SUFFIXES})
    item = estimate(["x", "y", "z", "vx", "vy", "vz"], np.ones(6), np.eye(6), source="ekf")
    got = [(topic, type_name) for topic, type_name, _ in sv.encoded(item)]
    assert got == [
        ("/ekf/odometry", views.ODOMETRY_TYPE),
        ("/ekf/diagnostics", views.DIAGNOSTICS_TYPE),
        ("/ekf/markers", views.MARKERS_TYPE),
    ]
    truth = views.StandardViews("truth", {s: f"/truth/{s}" for s in (views.ODOMETRY, views.MARKERS)})
    sample = TruthSample(0, 0, "eci", ["x", "y", "z", "vx", "vy", "vz"], np.ones(6))
    assert [t for t, _, _ in truth.encoded(sample)] == ["/truth/odometry", "/truth/markers"]
    assert all(type(data) is bytes for _, _, data in truth.encoded(sample))


def test_item_publishers_publish_each_item_then_its_views():
    class Shell:  # the part of BenchNode item_publishers uses
        def __init__(self):
            self.sent, self.publishers, self.warnings = [], [], []

        def get_name(self):
            return "ukf"

        def get_logger(self):
            return type("Logger", (), {"warning": lambda _, text: self.warnings.append(text)})()

        def item_publisher(self, topic, type_name):
            self.publishers.append(topic)
            return lambda item: self.sent.append((topic, item.step))

        def data_publisher(self, msg_type, topic):
            self.publishers.append(topic)

        def publish_data(self, topic, data):
            self.sent.append((topic, type(data)))

    shell = Shell()
    publishes = {"/ukf/estimate": "bench_msgs/msg/StateEstimate", "/ukf/stars": "bench_msgs/msg/StarCentroids"}
    publishes.update(views.view_topics("/ukf/estimate", "bench_msgs/msg/StateEstimate"))
    outputs = views.item_publishers(shell, publishes)
    assert sorted(outputs) == ["/ukf/estimate", "/ukf/stars"] and sorted(shell.publishers) == sorted(publishes)
    outputs["/ukf/estimate"](estimate(["x", "y", "z", "vx", "vy", "vz"], np.ones(6), np.eye(6)))
    assert shell.sent == [
        ("/ukf/estimate", 7),
        ("/ukf/odometry", bytes),
        ("/ukf/diagnostics", bytes),
        ("/ukf/markers", bytes),
    ]
    shell.sent.clear()
    later = 2 * int(views.DIAGNOSTICS_PERIOD_S * 1e9)  # a new diagnostics period: its diagnostics are built
    bad = estimate(
        ["x", "y", "z", "vx", "vy", "vz"],
        np.ones(6),
        np.eye(6),
        diagnostics={"n_eff": "many"},
        t_ns=12_300_000_000 + later,
    )
    outputs["/ukf/estimate"](bad)  # a view that fails is logged, the estimate is published
    outputs["/ukf/estimate"](bad)
    assert shell.sent[0] == ("/ukf/estimate", 7) and len(shell.warnings) == 1 and "not published" in shell.warnings[0]


def test_the_foxglove_layout_names_bench_topics_and_fields():
    """foxglove/bench_layout.json: every topic it shows is a view, an estimate or the truth, every Plot path a
    numeric field of that topic's message, and the layout tree holds exactly its panels."""
    layout = json.loads((Path(__file__).resolve().parent.parent / "foxglove" / "bench_layout.json").read_text())
    panels = layout["configById"]
    types = {
        **{s: t for s, t in views.ESTIMATE_VIEWS.items()},
        "estimate": "bench_msgs/msg/StateEstimate",
        "state": "bench_msgs/msg/TruthState",
    }

    def leaves(node):
        return [node] if isinstance(node, str) else leaves(node["first"]) + leaves(node["second"])

    assert sorted(leaves(layout["layout"])) == sorted(panels)
    paths = [p["value"] for cfg in panels.values() for p in cfg.get("paths", [])]
    assert len(paths) > 10
    for path in paths:
        topic, fields = re.fullmatch(r"(/\w+/\w+)\.(.+)", path).groups()
        msg = cdr.lite_class(types[topic.rsplit("/", 1)[1]])()
        for name, index in re.findall(r"(\w+)(?:\[(\d+)\])?", fields):
            msg = getattr(msg, name)
            msg = msg[int(index)] if index else msg
        assert isinstance(msg, (int, float, np.floating)), path
    shown = [*panels["3D!benchtrajectories"]["topics"], panels["DiagnosticSummary!benchdiagnostics"]["topicToRender"]]
    assert all(t.rsplit("/", 1)[1] in views.SUFFIXES for t in shown)
