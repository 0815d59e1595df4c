"""The bench's Fast DDS profile (bench_engine.dds_profile): Fast DDS loads it without an error, it sets the heartbeat
period the module states, and it never overrides a profile the user names."""

from __future__ import annotations

import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from bench_engine import dds_profile

NS = {"p": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}
PROBE = """
import rclpy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("profile_probe")
node.create_publisher(String, "profile_probe", 10).publish(String(data="x"))
node.destroy_node()
rclpy.shutdown()
"""


def _participant_output(profile: Path) -> str:
    """Output of a process that creates a participant and a writer with ``profile`` as its Fast DDS profile (Fast
    DDS logs its errors to stdout)."""
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", **{dds_profile.PROFILE_ENV: str(profile)})
    done = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    return done.stdout + done.stderr


def test_the_profile_sets_the_stated_heartbeat_as_the_default_writer_profile():
    root = ET.parse(dds_profile.PROFILE).getroot()
    writer = root.find("p:data_writer", NS)
    assert writer is not None and writer.get("is_default_profile") == "true"
    period = writer.find("p:times/p:heartbeatPeriod", NS)
    seconds = int(period.find("p:sec", NS).text) + int(period.find("p:nanosec", NS).text) * 1e-9
    assert seconds == pytest.approx(dds_profile.HEARTBEAT_PERIOD_S)
    assert seconds < 3.0  # Fast DDS's default, the stall this profile removes


def test_fast_dds_loads_the_profile_without_an_error(tmp_path):
    assert "XMLPARSER" not in _participant_output(dds_profile.PROFILE)
    broken = tmp_path / "broken.xml"  # the same check sees a profile Fast DDS rejects
    broken.write_text(dds_profile.PROFILE.read_text().replace("<sec>0</sec>", "<sec>zero</sec>"))
    assert "XMLPARSER" in _participant_output(broken)


def test_a_profile_the_user_names_wins(monkeypatch):
    monkeypatch.setenv(dds_profile.PROFILE_ENV, "/etc/my_profile.xml")
    dds_profile.use_bench_profile()
    assert os.environ[dds_profile.PROFILE_ENV] == "/etc/my_profile.xml"
    monkeypatch.delenv(dds_profile.PROFILE_ENV)
    dds_profile.use_bench_profile()
    assert Path(os.environ[dds_profile.PROFILE_ENV]) == dds_profile.PROFILE
