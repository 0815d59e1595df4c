"""A bench filter node in someone else's ROS 2 graph: the installed ``filter_node`` console script, configured by
a parameters file alone, fed by a plain rclpy publisher written here (best-effort QoS, ``step`` left at 0, a
remapped topic, one malformed message and one duplicate), gives the estimates of the in-process run on the same
measurements; its parameters are read through rclpy's parameter client (the services ``ros2 param`` uses)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import rclpy
from rcl_interfaces.msg import ParameterType
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from bench_engine.config import apply_overrides, load_scenario
from bench_engine.domains import reserve
from bench_engine.inprocess import run_in_process
from bench_engine.launcher import _file_parameters, prepare_run
from bench_engine.parameters import node_parameters, parameters_file
from bench_engine.stage_node import StageNode
from bench_msgs.msg import RangeAzEl, StateEstimate
from radar_sensor.messages import RANGE_AZ_EL

FILTER_NODE = Path(sys.executable).parent.parent / "lib" / "tracker_filters" / "filter_node"
MEASUREMENTS = "/elsewhere/radar_scans"
BEST_EFFORT = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50, reliability=ReliabilityPolicy.BEST_EFFORT)
MALFORMED_AFTER, DUPLICATE_AFTER = 5, 12


@pytest.fixture(scope="module")
def reference():
    """The leo_radar UKF's measurements and estimates, run in process (no ROS)."""
    cfg = apply_overrides(load_scenario("leo_radar"), ["time.duration=12", "sensors.radar.p_detect=1.0"])
    run = run_in_process(cfg, ["ukf"], seed=5)
    return cfg, run.items["/radar/measurement"], run.items["/ukf/estimate"]


@pytest.fixture()
def ros(tmp_path: Path, reference):
    """A free ROS domain with the standalone UKF running on it and a test node of ours."""
    cfg = reference[0]
    params = tmp_path / "ukf.yaml"
    params.write_text(parameters_file(node_parameters(cfg, "filter", "ukf")))
    reservation = reserve(None)
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(reservation.domain))
    log = open(tmp_path / "ukf.log", "w")
    proc = subprocess.Popen(
        [
            str(FILTER_NODE),
            "--ros-args",
            "-r",
            "__node:=ukf",
            "--params-file",
            str(params),
            "-p",
            "qos.reliability:=best_effort",
            "-p",
            "qos.history:=keep_last",
            "-r",
            f"radar/measurement:={MEASUREMENTS}",
        ],
        env=env,
        stdout=log,
        stderr=subprocess.STDOUT,
        start_new_session=True,
    )
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=reservation.domain)
    node = rclpy.create_node("foreign_radar_driver", context=context)
    executor = rclpy.executors.SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        yield node, executor, proc, tmp_path / "ukf.log"
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            proc.wait(timeout=15)
        log.close()
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)
        reservation.release()


def _spin_until(executor, done, timeout_s: float = 20.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while not done() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.02)
    return done()


def _message(item) -> RangeAzEl:
    msg = RANGE_AZ_EL.encode(item, RangeAzEl)
    msg.step = 0  # a foreign driver knows nothing of the bench's step counter
    msg.covariance = [float(v) for v in msg.covariance]
    return msg


def test_a_standalone_ukf_on_a_foreign_best_effort_topic_equals_the_in_process_run(ros, reference) -> None:
    node, executor, proc, log = ros
    _cfg, measurements, expected = reference
    received: list[StateEstimate] = []
    pub = node.create_publisher(RangeAzEl, MEASUREMENTS, BEST_EFFORT)
    node.create_subscription(StateEstimate, "/ukf/estimate", received.append, BEST_EFFORT)
    assert _spin_until(
        executor, lambda: pub.get_subscription_count() > 0 and node.count_publishers("/ukf/estimate") > 0
    ), "the standalone node never came up"
    # The writer matched the node's reader; the reader may not know the writer yet and then drops its best-effort
    # data: a driver's first scan is repeated until the filter has started (a repeat after that is a duplicate).
    for _ in range(40):
        pub.publish(_message(measurements[0]))
        if _spin_until(executor, lambda: received, timeout_s=0.5):
            break
    assert received, "the filter never started"
    expected_by_t = {e.t_ns: e for e in expected}
    for i, item in enumerate(measurements[1:], start=1):
        pub.publish(_message(item))
        if item.t_ns in expected_by_t:
            assert _spin_until(
                executor, lambda t_ns=item.t_ns: len(received) == len([e for e in expected if e.t_ns <= t_ns])
            ), f"no estimate for measurement {i}"
        if i == MALFORMED_AFTER:
            pub.publish(b"\x00\x01\x00\x00" + b"\xff" * 9)  # CDR bytes that are no RangeAzEl
        if i == DUPLICATE_AFTER:
            pub.publish(_message(item))  # the same stamp again
    _spin_until(executor, lambda: False, timeout_s=0.5)  # nothing more may arrive
    assert proc.poll() is None, "the node ended"
    assert len(received) == len(expected) > 50
    for got, want in zip(received, expected):
        assert got.step == 0 and got.header.frame_id == want.frame_id
        assert got.header.stamp.sec * 1_000_000_000 + got.header.stamp.nanosec == want.t_ns
        np.testing.assert_allclose(got.state, want.x, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(np.reshape(got.covariance, want.P.shape), want.P, rtol=1e-9, atol=1e-9)
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=15) == 0
    text = log.read_text()
    assert f"{MEASUREMENTS}: skipped a malformed bench_msgs/msg/RangeAzEl message" in text
    assert "duplicated or out-of-order" in text


def test_a_running_filter_node_shows_its_type_and_tuning_as_read_only_parameters(ros) -> None:
    node, executor, _proc, _log = ros
    client = AsyncParameterClient(node, "ukf")
    assert client.wait_for_services(timeout_sec=20.0)
    names = [
        "kind",
        "filters.ukf.type",
        "filters.ukf.params.alpha",
        "filters.ukf.dynamics.model",
        "sensors.radar.sigma_range",
        "qos.reliability",
        "earth.mu",
    ]
    future = client.get_parameters(names)
    executor.spin_until_future_complete(future, timeout_sec=10.0)
    values = dict(zip(names, (v.string_value or v.double_value for v in future.result().values)))
    assert values == {
        "kind": "filter",
        "filters.ukf.type": "ukf",
        "filters.ukf.params.alpha": 1.0,
        "filters.ukf.dynamics.model": "orbit_j2",
        "sensors.radar.sigma_range": 31.6227766,
        "qos.reliability": "best_effort",
        "earth.mu": 3.986004418e14,
    }
    types = {name: v.type for name, v in zip(names, future.result().values)}
    assert types["earth.mu"] == types["filters.ukf.params.alpha"] == ParameterType.PARAMETER_DOUBLE
    listed = client.list_parameters(prefixes=["filters.ukf"])
    executor.spin_until_future_complete(listed, timeout_sec=10.0)
    assert "filters.ukf.init.velocity_sigma" in listed.result().result.names
    described = client.describe_parameters(["filters.ukf.params.alpha"])
    executor.spin_until_future_complete(described, timeout_sec=10.0)
    descriptor = described.result().descriptors[0]
    assert descriptor.read_only and "filters.ukf.params.alpha" in descriptor.description
    refused = client.set_parameters([rclpy.parameter.Parameter("filters.ukf.params.alpha", value=0.5)])
    executor.spin_until_future_complete(refused, timeout_sec=10.0)
    assert not refused.result().results[0].successful


def test_a_standalone_node_with_a_missing_parameter_says_which_in_one_line(tmp_path: Path) -> None:
    params = tmp_path / "bad.yaml"
    params.write_text(parameters_file({"filters.ukf.type": "ukf", "sensors.radar.type": "ground_radar"}))
    reservation = reserve(None)
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(reservation.domain))
    try:
        res = subprocess.run(
            [str(FILTER_NODE), "--ros-args", "-r", "__node:=ukf", "--params-file", str(params)],
            capture_output=True,
            text=True,
            timeout=60,
            env=env,
        )
    finally:
        reservation.release()
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "filters.ukf" in lines[0] and "Traceback" not in res.stderr


def test_a_bench_mode_node_is_configured_by_the_parameters_file_the_launcher_wrote(tmp_path: Path) -> None:
    """The ukf of a prepared leo_radar run, created as the launcher creates it (run config + its params file)
    and spinning while it waits for the run to start, shows the scenario's settings, --set included."""
    plan = prepare_run("leo_radar", tmp_path / "run", overrides=["filters.ukf.params.alpha=0.5"])
    assert "filters.ukf.params.alpha: 0.5" in plan.parameters_file("ukf").read_text()
    reservation = reserve(None)
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=reservation.domain)
    try:
        ukf = StageNode("ukf", plan.run, parameters=_file_parameters(plan, "ukf"), context=context)
        probe = rclpy.create_node("probe", context=context)
        executor = rclpy.executors.SingleThreadedExecutor(context=context)
        for node in (ukf, probe):
            executor.add_node(node)
        client = AsyncParameterClient(probe, "ukf")
        assert client.wait_for_services(timeout_sec=20.0)
        future = client.get_parameters(["kind", "filters.ukf.type", "filters.ukf.params.alpha"])
        executor.spin_until_future_complete(future, timeout_sec=10.0)
        kind, type_, alpha = future.result().values
        assert (kind.string_value, type_.string_value, alpha.double_value) == ("filter", "ukf", 0.5)
        assert ukf.stage.stack.filter.points.alpha == 0.5
        executor.shutdown()
    finally:
        rclpy.shutdown(context=context)
        reservation.release()
