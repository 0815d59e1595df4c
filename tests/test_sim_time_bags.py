"""Bags on the sim's time line: every recorded message's log and publish time is its sim time
(bench_engine.sim_clock, the recorder's rule), so Foxglove, PlotJuggler, rosbags and ``ros2 bag play`` show a
420 s pass as 420 s. Checked on the rule itself for any message type and hostile bytes, then on real graph runs
read by rosbags and by mcap's reader: recorded, recovered after the recorder was killed, and replayed."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from graph_helpers import launch_in_background, node_pid, script, wait_for_stepping
from mcap.data_stream import ReadDataStream
from mcap.reader import make_reader
from mcap.records import Chunk, ChunkIndex, Message
from mcap.stream_reader import breakup_chunk
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.highlevel import AnyReader

from bench_engine.bag_reader import BagReader
from bench_engine.bag_writer import CHUNK_SIZE
from bench_engine.msg_schema import message_class
from bench_engine.recorder_node import FLUSH_SIM_S, FLUSH_WALL_S, WALL_DURATION_KEY, WALL_START_KEY
from bench_engine.sim_clock import SimClock, StampRule, leading_stamp_ns, stamp_rule
from bench_engine.views import SUFFIXES
from bench_eval.scoring import load_bag

START_NS = 4_320_800_000_000  # leo_radar's time.start
DT_NS = 100_000_000
DURATION_NS = 30_000_000_000
STEPS = DURATION_NS // DT_NS + 1
SIM_30_S = ["--set", "time.duration=30"]


# --- the rule, for any message type ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    "type_name, rule",
    [
        ("bench_msgs/msg/TruthState", StampRule.HEADER),
        ("bench_msgs/msg/StateEstimate", StampRule.HEADER),
        ("nav_msgs/msg/Odometry", StampRule.HEADER),
        ("diagnostic_msgs/msg/DiagnosticArray", StampRule.HEADER),
        ("geometry_msgs/msg/PoseWithCovarianceStamped", StampRule.HEADER),
        ("rosgraph_msgs/msg/Clock", StampRule.CLOCK),
        ("rosgraph_msgs/Clock", StampRule.CLOCK),
        ("visualization_msgs/msg/MarkerArray", StampRule.LATEST_CLOCK),
        ("std_msgs/msg/String", StampRule.LATEST_CLOCK),
        ("geometry_msgs/msg/Point", StampRule.LATEST_CLOCK),
        ("bench_msgs/msg/StepAck", StampRule.LATEST_CLOCK),
    ],
)
def test_the_rule_follows_the_message_definition(type_name: str, rule: StampRule) -> None:
    assert stamp_rule(type_name) is rule


def _stamped(type_name: str, sec: int, nanosec: int) -> bytes:
    """rclpy's CDR bytes of a message of ``type_name`` with that stamp and some content after it."""
    msg = message_class(type_name)()
    stamp = msg.clock if type_name == "rosgraph_msgs/msg/Clock" else msg.header.stamp
    stamp.sec, stamp.nanosec = sec, nanosec
    if hasattr(msg, "header"):
        msg.header.frame_id = "odom"
    if type_name == "nav_msgs/msg/Odometry":
        msg.child_frame_id, msg.pose.pose.position.x = "base_link", 1.5
    if type_name == "diagnostic_msgs/msg/DiagnosticArray":
        msg.status = [message_class("diagnostic_msgs/msg/DiagnosticStatus")(name="radar", message="ok")]
    return serialize_message(msg)


@pytest.mark.parametrize(
    "type_name",
    [
        "nav_msgs/msg/Odometry",
        "diagnostic_msgs/msg/DiagnosticArray",
        "bench_msgs/msg/RangeAzEl",
        "rosgraph_msgs/msg/Clock",
    ],
)
def test_the_stamp_is_read_from_the_cdr_bytes(type_name: str) -> None:
    rng = np.random.default_rng(17)
    cases = [(0, 0), (2**31 - 1, 999_999_999), (4320, 800_000_000)]
    cases += [(int(rng.integers(0, 2**31)), int(rng.integers(0, 10**9))) for _ in range(50)]
    for sec, nanosec in cases:
        assert leading_stamp_ns(_stamped(type_name, sec, nanosec)) == sec * 1_000_000_000 + nanosec


def test_big_endian_cdr_is_read_and_other_encodings_fall_back() -> None:
    time_be = (7).to_bytes(4, "big") + (5).to_bytes(4, "big")
    assert leading_stamp_ns(b"\x00\x00\x00\x00" + time_be + b"\x00" * 8) == 7_000_000_005
    little = _stamped("nav_msgs/msg/Odometry", 7, 5)
    for encapsulation in (b"\x00\x03", b"\x00\x07", b"\x01\x01"):  # PL_CDR, XCDR2, not an encapsulation at all
        assert leading_stamp_ns(encapsulation + little[2:]) is None
    negative = little[:4] + (-3).to_bytes(4, "little", signed=True) + little[8:]
    assert leading_stamp_ns(negative) is None
    assert leading_stamp_ns(little[:8] + (10**9).to_bytes(4, "little") + little[12:]) is None


def test_sim_clock_contract_and_hostile_bytes() -> None:
    clock = SimClock(START_NS)
    for topic, type_name in [
        ("/clock", "rosgraph_msgs/msg/Clock"),
        ("/odom", "nav_msgs/msg/Odometry"),
        ("/markers", "visualization_msgs/msg/MarkerArray"),
    ]:
        clock.add_topic(topic, type_name)
    markers = serialize_message(message_class("visualization_msgs/msg/MarkerArray")())
    assert clock.log_time_ns("/markers", markers) == START_NS  # before the first clock: the run's start
    assert clock.log_time_ns("/clock", _stamped("rosgraph_msgs/msg/Clock", 4321, 0)) == 4_321_000_000_000
    assert clock.log_time_ns("/odom", _stamped("nav_msgs/msg/Odometry", 4320, 900_000_000)) == 4_320_900_000_000
    assert clock.log_time_ns("/markers", markers) == 4_321_000_000_000  # the latest clock, not the latest stamp
    rng = np.random.default_rng(3)
    for n in range(12):  # too short to hold a stamp: the latest clock, and a short clock does not move it
        junk = rng.bytes(n)
        assert [clock.log_time_ns(t, junk) for t in ("/odom", "/clock", "/markers")] == [4_321_000_000_000] * 3
    for invalid in ((-1, 0), (-1, 999_999_999), (5, 10**9), (-1, 2**32 - 1)):  # before 0, nanosec out of range
        time_le = invalid[0].to_bytes(4, "little", signed=True) + invalid[1].to_bytes(4, "little")
        assert clock.log_time_ns("/odom", b"\x00\x01\x00\x00" + time_le) == 4_321_000_000_000
    with pytest.raises(KeyError):
        clock.log_time_ns("/undeclared", markers)


# --- a real run ------------------------------------------------------------------------------------------------


def _stamp_ns(msg) -> int:
    """The sim time a decoded message carries: a Clock's clock, else its header stamp."""
    stamp = msg.clock if hasattr(msg, "clock") else msg.header.stamp
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def _rosbags_times(bag: Path) -> list[tuple[str, int, int]]:
    """(topic, log time, sim stamp) of every message, as rosbags' AnyReader returns them."""
    with AnyReader([bag]) as reader:
        rows = [(c.topic, t, _stamp_ns(reader.deserialize(raw, c.msgtype))) for c, t, raw in reader.messages()]
        assert len(rows) == reader.message_count
    return rows


def _metadata(bag: Path) -> dict:
    return yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]


def _chunks(mcap: Path) -> list[tuple[ChunkIndex, list[Message]]]:
    """(chunk index, its message records in file order) of every chunk."""
    with open(mcap, "rb") as f:
        indexes = make_reader(f).get_summary().chunk_indexes
        out = []
        for index in indexes:
            f.seek(index.chunk_start_offset + 1 + 8)
            records = breakup_chunk(Chunk.read(ReadDataStream(f)))
            out.append((index, [r for r in records if isinstance(r, Message)]))
    return out


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("sim_time") / "run"
    res = script("launch.py", "leo_radar", "--seed", "5", "--out", str(out), "--no-score", *SIM_30_S)
    assert res.returncode == 0, res.stderr[-3000:]
    return out


def test_rosbags_sees_log_times_equal_to_sim_time(run: Path) -> None:
    rows = _rosbags_times(run / "bag")
    assert {topic for topic, _, _ in rows if topic.rsplit("/", 1)[1] not in SUFFIXES} == {  # beside the views
        "/truth/state",
        "/clock",
        "/radar/measurement",
        "/ekf/estimate",
        "/ukf/estimate",
    }
    assert [(topic, t) for topic, t, s in rows if t != s] == []
    log_times = [t for _, t, _ in rows]
    assert log_times == sorted(log_times)
    assert log_times[0] == START_NS
    assert abs(log_times[-1] - log_times[0] - DURATION_NS) <= DT_NS
    assert sum(topic == "/truth/state" for topic, _, _ in rows) == STEPS


def test_mcap_reader_chunk_indexes_and_statistics_are_in_sim_time(run: Path) -> None:
    mcap = next((run / "bag").glob("*.mcap"))
    with open(mcap, "rb") as f:
        reader = make_reader(f)
        stats = reader.get_summary().statistics
        in_file = [(c.topic, m) for _, c, m in reader.iter_messages(log_time_order=False)]
        in_time = [m.log_time for _, _, m in reader.iter_messages()]
    decode = {topic: message_class(t) for topic, t in BagReader(run / "bag").topics().items()}
    for topic, m in in_file:
        assert m.log_time == m.publish_time == _stamp_ns(deserialize_message(m.data, decode[topic])), topic
    log_times = [m.log_time for _, m in in_file]
    assert len(in_time) == len(in_file) == stats.message_count and in_time == sorted(log_times)
    assert (stats.message_start_time, stats.message_end_time) == (START_NS, max(log_times))
    chunks = _chunks(mcap)
    assert sum(len(messages) for _, messages in chunks) == len(in_file)
    # chunks end at a flush (at most one per FLUSH_WALL_S of the run's wall span, and one per FLUSH_SIM_S of its
    # sim time) or when full (CHUNK_SIZE uncompressed), and at the close
    wall_s = int(_metadata(run / "bag")["custom_data"][WALL_DURATION_KEY]) * 1e-9
    full = sum(index.uncompressed_size for index, _ in chunks) // CHUNK_SIZE
    assert len(chunks) <= min(wall_s / FLUSH_WALL_S, DURATION_NS * 1e-9 / FLUSH_SIM_S) + full + 2
    for index, messages in chunks:
        times = [m.log_time for m in messages]
        assert (index.message_start_time, index.message_end_time) == (min(times), max(times))


def test_metadata_gives_the_sim_start_and_duration_and_keeps_the_wall_span(run: Path) -> None:
    info = _metadata(run / "bag")
    assert info["starting_time"] == {"nanoseconds_since_epoch": START_NS}
    assert abs(info["duration"]["nanoseconds"] - DURATION_NS) <= DT_NS
    assert info["files"][0]["starting_time"] == info["starting_time"]
    assert info["files"][0]["duration"] == info["duration"]
    wall_start, wall_span = int(info["custom_data"][WALL_START_KEY]), int(info["custom_data"][WALL_DURATION_KEY])
    assert abs(wall_start - time.time_ns()) < 3600 * 10**9 and 0 < wall_span < 600 * 10**9


def test_the_scorer_reads_the_run_by_step(run: Path) -> None:
    data = load_bag(run / "bag")
    assert sorted(data.truth) == list(range(STEPS))
    assert data.truth[0][0] == pytest.approx(START_NS * 1e-9)
    assert set(data.estimates) == {"ekf", "ukf"}


def test_a_bag_recovered_after_the_recorder_is_killed_has_sim_log_times(tmp_path: Path) -> None:
    out = tmp_path / "killed"
    proc = launch_in_background(out)
    try:
        wait_for_stepping(out, proc)
        os.kill(node_pid(out, "recorder"), signal.SIGKILL)
        _, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert "node 'recorder' died first (killed by SIGKILL)" in err and "recovered" in err
    assert list((out / "bag").glob("*.mcap.truncated"))
    rows = _rosbags_times(out / "bag")
    assert [(topic, t) for topic, t, s in rows if t != s] == []
    log_times = [t for _, t, _ in rows]
    assert log_times[0] == START_NS and len(log_times) > 10
    info = _metadata(out / "bag")
    assert info["starting_time"]["nanoseconds_since_epoch"] == START_NS
    assert info["duration"]["nanoseconds"] == log_times[-1] - START_NS
    assert "sim time 4320.8–" in err


def test_a_replayed_bag_is_in_sim_time_and_replays_by_step(run: Path, tmp_path: Path) -> None:
    out = tmp_path / "replay"
    res = script("replay.py", str(run / "bag"), "--estimators", "ukf", "--out", str(out))
    assert res.returncode == 0, res.stderr[-3000:]
    rows = _rosbags_times(out / "bag")
    assert [(topic, t) for topic, t, s in rows if t != s] == []
    assert rows[0][1] == START_NS
    recorded, replayed = (
        BagReader(bag).tables(["/ukf/estimate"])["/ukf/estimate"] for bag in (run / "bag", out / "bag")
    )
    np.testing.assert_array_equal(replayed["step"], recorded["step"])
    np.testing.assert_array_equal(replayed["state"], recorded["state"])
