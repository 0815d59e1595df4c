"""rosbag2-compatible MCAP bags: our writer, read back by independent readers (rosbags, mcap-ros2-support)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer
from mcap_ros2.decoder import DecoderFactory
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

import orbit_sim
from bench_engine.bag_metadata import dump_yaml, offered_qos
from bench_engine.bag_reader import BagReader
from bench_engine.bag_writer import BagWriter, FlushSchedule
from bench_engine.msg_schema import SEPARATOR, dependencies, message_class, msg_text, schema_text, type_hash

T0_NS = 1_700_000_000_000_000_000
STEPS = 40
TOPICS = {
    "/truth": "bench_msgs/msg/TruthState",
    "/radar": "bench_msgs/msg/RangeAzEl",
    "/gps": "bench_msgs/msg/VectorMeasurement",
    "/estimate": "bench_msgs/msg/StateEstimate",
    "/sim/ack": "bench_msgs/msg/StepAck",
    "/chatter": "std_msgs/msg/String",
    "/clock": "rosgraph_msgs/msg/Clock",
}
CLOCK_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.BEST_EFFORT,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
ACK_QOS = [{"history": "keep_all", "depth": 0}, {"reliability": "best_effort", "deadline": 1_500_000_000}]


def _stamp(msg, t_ns: int, frame: str) -> None:
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t_ns, 1_000_000_000)
    msg.header.frame_id = frame


def _messages_for_step(k: int, t_ns: int, rng: np.random.Generator) -> dict[str, object]:
    """One message of every topic, with every array filled."""
    cls = {topic: message_class(t) for topic, t in TOPICS.items()}
    truth = cls["/truth"](step=k, labels=["x", "y", "z", "vx", "vy", "vz"], state=rng.normal(size=6).tolist())
    _stamp(truth, t_ns, "eci")
    radar = cls["/radar"](
        step=k,
        sensor_id="radar_1",
        range=7.0e6 + k,
        azimuth=0.1 * k,
        elevation=0.2,
        range_rate=float(rng.normal()),
        has_range_rate=bool(k % 2),
        covariance=rng.normal(size=16),
    )
    _stamp(radar, t_ns, "radar_enu")
    gps = cls["/gps"](
        step=k,
        sensor_id="gps",
        labels=["x", "y", "z"],
        value=rng.normal(size=3).tolist(),
        covariance=rng.normal(size=9).tolist(),
    )
    _stamp(gps, t_ns, "eci")
    estimate = cls["/estimate"](
        step=k,
        filter_name="ekf",
        labels=["x", "y", "z", "vx", "vy", "vz"],
        state=rng.normal(size=6).tolist(),
        covariance=rng.normal(size=36).tolist(),
        nis=float("nan") if k == 0 else float(rng.chisquare(3)),
        diagnostic_names=["n_eff", "iterations"],
        diagnostic_values=rng.uniform(size=2).tolist(),
    )
    _stamp(estimate, t_ns, "eci")
    ack = cls["/sim/ack"](node="radar_1", step=k, count=2 * k + 1)
    chatter = cls["/chatter"](data=f"step {k} ✓")
    clock = cls["/clock"]()
    clock.clock.sec, clock.clock.nanosec = divmod(t_ns, 1_000_000_000)
    return {
        "/truth": truth,
        "/radar": radar,
        "/gps": gps,
        "/estimate": estimate,
        "/sim/ack": ack,
        "/chatter": chatter,
        "/clock": clock,
    }


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    """A bag of STEPS steps of all seven topics, plus one declared topic without messages."""
    directory = tmp_path_factory.mktemp("bags") / "run_bag"
    rng = np.random.default_rng(7)
    written: list[tuple[str, int, int, object, bytes]] = []
    with BagWriter(directory) as writer:
        for topic, type_name in TOPICS.items():
            qos = {"/clock": CLOCK_QOS, "/sim/ack": ACK_QOS}.get(topic)
            writer.add_topic(topic, type_name, qos)
        writer.add_topic("/unused", "std_msgs/msg/String")
        for k in range(STEPS):
            t_ns = T0_NS + k * 10_000_000
            for i, (topic, msg) in enumerate(_messages_for_step(k, t_ns, rng).items()):
                data = serialize_message(msg)
                log_ns, pub_ns = t_ns + i, t_ns - 1000 * (i + 1)
                writer.write(topic, data, log_ns, pub_ns)
                written.append((topic, log_ns, pub_ns, msg, data))
    return directory, written


def _assert_same(expected, actual, path: str = "") -> None:
    """Field-by-field equality of a generated ROS message and a message decoded by another library."""
    for name in expected.get_fields_and_field_types():
        want, got = getattr(expected, name), getattr(actual, name)
        where = f"{path}.{name}"
        if hasattr(want, "get_fields_and_field_types"):
            _assert_same(want, got, where)
        elif isinstance(want, (str, bool, int, float)):
            assert got == want or (want != want and got != got), where
        else:
            np.testing.assert_array_equal(np.asarray(list(got)), np.asarray(list(want)), err_msg=where)


def _by_topic(written):
    out: dict[str, list] = {}
    for topic, log_ns, pub_ns, msg, data in written:
        out.setdefault(topic, []).append((log_ns, pub_ns, msg, data))
    return out


# --- message definitions ---------------------------------------------------------------------------------


def test_schema_text_is_rosbag2_layout():
    sep = "\n" + SEPARATOR + "\n"
    expected = (
        msg_text("bench_msgs/msg/RangeAzEl")
        + sep
        + "MSG: std_msgs/Header\n"
        + msg_text("std_msgs/msg/Header")
        + sep
        + "MSG: builtin_interfaces/Time\n"
        + msg_text("builtin_interfaces/msg/Time")
    )
    assert schema_text("bench_msgs/msg/RangeAzEl") == expected
    assert schema_text("bench_msgs/msg/StepAck") == msg_text("bench_msgs/msg/StepAck")


def test_dependencies_are_found_depth_first_in_sorted_order():
    order = [
        line[5:]
        for line in schema_text("geometry_msgs/msg/PoseWithCovarianceStamped").splitlines()
        if line.startswith("MSG: ")
    ]
    assert order == [
        "geometry_msgs/PoseWithCovariance",
        "geometry_msgs/Pose",
        "geometry_msgs/Point",
        "geometry_msgs/Quaternion",
        "std_msgs/Header",
        "builtin_interfaces/Time",
    ]


def test_dependency_parsing_skips_primitives_constants_and_comments():
    text = textwrap.dedent("""\
        # geometry_msgs/Twist in a comment is not a field
        uint8 MODE_A=1
        string NAME="std_msgs/Empty"
        float64 gain 0.5   # default value; nav_msgs/Odometry in a trailing comment
        int32[] values [1, 2]
        string<=8 short_name
        string<=5[<=3] names
          geometry_msgs/Point[] points
        Pose[3] poses
        std_msgs/Header[<=2] headers
        builtin_interfaces/Time stamp
        """)
    assert dependencies(text, "mypkg") == [
        "builtin_interfaces/Time",
        "geometry_msgs/Point",
        "mypkg/Pose",
        "std_msgs/Header",
    ]


@pytest.mark.parametrize("type_name", [*TOPICS.values(), "nav_msgs/msg/Odometry"])
def test_embedded_definition_hashes_to_the_installed_type_hash(type_name):
    """rosbags parses our schema text and computes RIHS01 itself: it must equal rosidl's hash."""
    store = get_typestore(Stores.EMPTY)
    store.register(get_types_from_msg(schema_text(type_name), type_name))
    assert store.hash_rihs01(type_name) == type_hash(type_name)
    assert type_hash(type_name).startswith("RIHS01_")


def test_message_class_and_short_type_names():
    assert message_class("bench_msgs/msg/StepAck").__name__ == "StepAck"
    assert schema_text("std_msgs/Header") == schema_text("std_msgs/msg/Header")
    assert type_hash("std_msgs/Header") == type_hash("std_msgs/msg/Header")
    with pytest.raises(ValueError):
        schema_text("not a type")
    with pytest.raises(FileNotFoundError):
        schema_text("bench_msgs/msg/NoSuchType")


# --- independent readers ---------------------------------------------------------------------------------


@pytest.mark.parametrize("which", ["directory", "bare_mcap"])
def test_rosbags_reads_bag(bag, which):
    directory, written = bag
    path = directory if which == "directory" else directory / "run_bag_0.mcap"
    expected = _by_topic(written)
    with AnyReader([path]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert counts == {**{t: STEPS for t in TOPICS}, "/unused": 0}
        assert {c.topic: c.msgtype for c in reader.connections if c.topic in TOPICS} == TOPICS
        assert reader.message_count == STEPS * len(TOPICS)
        assert reader.start_time == written[0][1]
        assert reader.end_time == written[-1][1] + 1
        got: dict[str, list] = {}
        for connection, log_ns, raw in reader.messages():
            got.setdefault(connection.topic, []).append((log_ns, reader.deserialize(raw, connection.msgtype)))
    for topic, items in expected.items():
        assert [t for t, _ in got[topic]] == [e[0] for e in items]
        for (_, msg), (_, _, want, _) in zip(got[topic], items):
            _assert_same(want, msg, topic)


def test_mcap_ros2_decoder_reads_bag(bag):
    directory, written = bag
    expected = _by_topic(written)
    got: dict[str, list] = {}
    with open(directory / "run_bag_0.mcap", "rb") as f:
        for schema, channel, message, decoded in make_reader(
            f, decoder_factories=[DecoderFactory()]
        ).iter_decoded_messages():
            got.setdefault(channel.topic, []).append((schema.name, message, decoded))
    assert set(got) == set(TOPICS)
    for topic, items in expected.items():
        assert [(m.log_time, m.publish_time) for _, m, _ in got[topic]] == [(e[0], e[1]) for e in items]
        assert {name for name, _, _ in got[topic]} == {TOPICS[topic]}
        for (_, _, msg), (_, _, want, _) in zip(got[topic], items):
            _assert_same(want, msg, topic)


@pytest.mark.parametrize("which", ["directory", "bare_mcap"])
def test_own_reader(bag, which):
    directory, written = bag
    reader = BagReader(directory if which == "directory" else directory / "run_bag_0.mcap")
    assert reader.topics() == {**TOPICS, "/unused": "std_msgs/msg/String"}
    rows = list(reader.messages())
    assert sorted((r[2], r[0], r[3]) for r in rows) == sorted((e[1], e[0], e[4]) for e in written)
    assert [r[2] for r in rows] == sorted(r[2] for r in rows)
    assert all(TOPICS[r[0]] == r[1] for r in rows)
    decoded = list(reader.decoded(topics=["/estimate", "/clock"]))
    expected = [e for e in written if e[0] in ("/estimate", "/clock")]
    assert [(d[0], d[1]) for d in decoded] == [(e[0], e[1]) for e in expected]
    for (_, _, msg), (_, _, _, want, _) in zip(decoded, expected):
        assert msg == want or msg.nis != msg.nis  # NaN nis of step 0 never compares equal
        _assert_same(want, msg)


@pytest.mark.parametrize("compression", [CompressionType.ZSTD, CompressionType.LZ4, CompressionType.NONE])
def test_payloads_are_every_message_of_the_topics_asked_in_written_order(tmp_path, compression):
    """BagReader.payloads walks the chunks itself: the same bytes as mcap's reader, per topic and in order, for
    every chunk compression MCAP defines, many chunks, and topics that are absent from some chunks."""
    path = tmp_path / "many_chunks.mcap"
    rng = np.random.default_rng(7)
    with open(path, "wb") as f:
        writer = Writer(f, chunk_size=2000, compression=compression)
        writer.start(profile="ros2", library="test")
        schema = writer.register_schema("std_msgs/msg/String", "ros2msg", b"string data")
        channels = {t: writer.register_channel(t, "cdr", schema) for t in ("/a", "/b", "/rare")}
        for k in range(600):
            topic = "/rare" if k % 97 == 0 else ("/a", "/b")[int(rng.integers(2))]
            writer.add_message(channels[topic], k, rng.bytes(int(rng.integers(0, 60))), k)
        writer.finish()
    reader = BagReader(path)
    mcap_order: dict[str, list[bytes]] = {}
    with open(path, "rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages(log_time_order=False):
            mcap_order.setdefault(channel.topic, []).append(message.data)
    assert len(make_reader(open(path, "rb")).get_summary().chunk_indexes) > 10
    assert reader.payloads(["/a", "/rare", "/absent"]) == {t: mcap_order[t] for t in ("/a", "/rare")}
    assert reader.payloads(["/b"]) == {"/b": mcap_order["/b"]}


def _out_of_order_bag(directory: Path) -> tuple[list[tuple[str, int, bytes]], list[tuple[int, int]]]:
    """A bag written as the recorder writes sim-time log times: the estimate of step k after the truth of step
    k + 3, a chunk ended every 10 steps (so chunks overlap in log time). Returns (topic, log time, bytes) in
    the order written, and each chunk's least and greatest log time."""
    written, spans, chunk = [], [], []
    with BagWriter(directory) as writer:
        writer.add_topic("/truth", TOPICS["/truth"])
        writer.add_topic("/estimate", TOPICS["/estimate"])
        for k in range(STEPS + 3):
            t_ns = T0_NS + k * 100_000_000
            items = [("/truth", t_ns)] if k < STEPS else []
            items += [("/estimate", t_ns - 300_000_000)] if k >= 3 else []
            for topic, log_ns in items:
                msg = message_class(TOPICS[topic])(step=(log_ns - T0_NS) // 100_000_000)
                _stamp(msg, log_ns, "eci")
                data = serialize_message(msg)
                writer.write(topic, data, log_ns)
                written.append((topic, log_ns, data))
                chunk.append(log_ns)
            if k % 10 == 9 or k == STEPS + 2:
                writer.flush()
                spans.append((min(chunk), max(chunk)))
                chunk = []
    return written, spans


@pytest.mark.parametrize("which", ["directory", "bare_mcap"])
def test_out_of_order_log_times_are_read_whole_by_every_reader(tmp_path, which):
    directory = tmp_path / "ooo"
    written, spans = _out_of_order_bag(directory)
    mcap = directory / "ooo_0.mcap"
    in_time = sorted(written, key=lambda w: w[1])  # stable: equal log times in written order
    assert in_time != written
    with AnyReader([directory if which == "directory" else mcap]) as reader:
        assert [(c.topic, t, bytes(raw)) for c, t, raw in reader.messages()] == in_time
    with open(mcap, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert [(c.topic, m.log_time, m.data) for _, c, m in reader.iter_messages()] == in_time
        assert [(c.topic, m.log_time, m.data) for _, c, m in reader.iter_messages(log_time_order=False)] == written
    assert [(t, n, d) for t, _, n, d in BagReader(mcap).messages()] == in_time
    assert BagReader(mcap).payloads(["/truth", "/estimate"]) == {
        topic: [d for t, _, d in written if t == topic] for topic in ("/truth", "/estimate")
    }
    assert (summary.statistics.message_start_time, summary.statistics.message_end_time) == (
        in_time[0][1],
        in_time[-1][1],
    )
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    assert [(c.message_start_time, c.message_end_time) for c in chunks] == spans
    assert any(b[0] < a[1] for a, b in zip(spans, spans[1:]))  # chunks overlap in log time
    info = yaml.safe_load((directory / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["starting_time"] == {"nanoseconds_since_epoch": in_time[0][1]}
    assert info["duration"] == {"nanoseconds": in_time[-1][1] - in_time[0][1]}


def test_custom_data_is_rosbag2s_map_of_strings(tmp_path):
    writer = BagWriter(tmp_path / "custom", custom_data={"operator": "bench"})
    writer.add_topic("/chatter", "std_msgs/msg/String")
    writer.set_custom_data({"wall_clock_start_ns": "17", "operator": "bench 2"})
    with pytest.raises(TypeError, match="strings to strings"):
        writer.set_custom_data({"wall_clock_start_ns": 17})
    writer.close()
    with pytest.raises(ValueError, match="closed"):
        writer.set_custom_data({"late": "x"})
    with pytest.raises(TypeError):
        BagWriter(tmp_path / "bad", custom_data={1: "x"})
    text = (tmp_path / "custom" / "metadata.yaml").read_text()
    info = yaml.safe_load(text)["rosbag2_bagfile_information"]
    assert info["custom_data"] == {"operator": "bench 2", "wall_clock_start_ns": "17"}
    with open(tmp_path / "custom" / "custom_0.mcap", "rb") as f:
        opened, closed = (yaml.safe_load(r.metadata["serialized_metadata"]) for r in make_reader(f).iter_metadata())
    assert opened["custom_data"] == {"operator": "bench"} and closed == info
    with AnyReader([tmp_path / "custom"]) as reader:
        assert [(c.topic, c.msgcount) for c in reader.connections] == [("/chatter", 0)]


# --- the rosbag2 records ---------------------------------------------------------------------------------


def test_mcap_records_are_those_rosbag2_writes(bag):
    directory, written = bag
    with open(directory / "run_bag_0.mcap", "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        records = [m for m in reader.iter_metadata() if m.name == "rosbag2"]
    assert {c.compression for c in summary.chunk_indexes} == {"zstd"}
    schemas = {s.name: s for s in summary.schemas.values()}
    assert len(schemas) == len(set(TOPICS.values())) == len(TOPICS)  # /unused shares std_msgs/String
    for name, schema in schemas.items():
        assert schema.encoding == "ros2msg"
        assert schema.data.decode() == schema_text(name)
    qos = {"/clock": CLOCK_QOS, "/sim/ack": ACK_QOS}
    for channel in summary.channels.values():
        assert channel.message_encoding == "cdr"
        assert channel.metadata["topic_type_hash"] == type_hash(summary.schemas[channel.schema_id].name)
        assert channel.metadata["offered_qos_profiles"] == dump_yaml(offered_qos(qos.get(channel.topic)))
    metadata = yaml.safe_load((directory / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    opened, closed = (yaml.safe_load(r.metadata["serialized_metadata"]) for r in records)
    assert closed == metadata
    assert opened["message_count"] == 0 and opened["starting_time"]["nanoseconds_since_epoch"] == 2**63 - 1


def test_metadata_yaml_version_9(bag):
    directory, written = bag
    text = (directory / "metadata.yaml").read_text()
    info = yaml.safe_load(text)["rosbag2_bagfile_information"]
    first, last = written[0][1], written[-1][1]
    assert info["version"] == 9 and info["storage_identifier"] == "mcap"
    assert info["message_count"] == len(written)
    assert info["starting_time"] == {"nanoseconds_since_epoch": first}
    assert info["duration"] == {"nanoseconds": last - first}
    assert info["relative_file_paths"] == ["run_bag_0.mcap"]
    assert info["files"] == [
        {
            "path": "run_bag_0.mcap",
            "starting_time": {"nanoseconds_since_epoch": first},
            "duration": {"nanoseconds": last - first},
            "message_count": len(written),
        }
    ]
    assert info["compression_format"] == "" and info["custom_data"] is None
    topics = {t["topic_metadata"]["name"]: t for t in info["topics_with_message_count"]}
    assert {name: t["message_count"] for name, t in topics.items()} == {**{n: STEPS for n in TOPICS}, "/unused": 0}
    clock = topics["/clock"]["topic_metadata"]
    assert clock["type_description_hash"] == type_hash("rosgraph_msgs/msg/Clock")
    assert clock["serialization_format"] == "cdr"
    assert clock["offered_qos_profiles"] == [
        {
            "history": "keep_last",
            "depth": 1,
            "reliability": "best_effort",
            "durability": "transient_local",
            "deadline": {"sec": 0, "nsec": 0},
            "lifespan": {"sec": 0, "nsec": 0},
            "liveliness": "system_default",
            "liveliness_lease_duration": {"sec": 0, "nsec": 0},
            "avoid_ros_namespace_conventions": False,
        }
    ]
    ack = topics["/sim/ack"]["topic_metadata"]["offered_qos_profiles"]
    assert [(q["history"], q["depth"], q["reliability"], q["deadline"]) for q in ack] == [
        ("keep_all", 0, "reliable", {"sec": 9223372036, "nsec": 854775807}),
        ("keep_last", 1000, "best_effort", {"sec": 1, "nsec": 500_000_000}),
    ]
    assert "  topics_with_message_count:\n    - topic_metadata:\n" in text  # yaml-cpp's sequence indentation
    assert 'compression_mode: ""' in text and "custom_data: ~" in text and "&id" not in text


# --- writer behaviour ------------------------------------------------------------------------------------


def test_writer_guards(tmp_path):
    data = serialize_message(message_class("std_msgs/msg/String")(data="x"))
    writer = BagWriter(tmp_path / "b")
    with pytest.raises(KeyError):
        writer.write("/chatter", data, 1)
    writer.add_topic("/chatter", "std_msgs/msg/String")
    writer.add_topic("/chatter", "std_msgs/msg/String")
    with pytest.raises(ValueError):
        writer.add_topic("/chatter", "bench_msgs/msg/StepAck")
    with pytest.raises(ValueError):
        writer.add_topic("/other", "std_msgs/msg/String", {"reliability": "sometimes"})
    with pytest.raises(ValueError):
        writer.add_topic("/other", "std_msgs/msg/String", {"reliabilty": "reliable"})
    writer.write("/chatter", bytearray(data), 5)
    writer.close()
    writer.close()
    assert writer.closed
    with pytest.raises(ValueError):
        writer.write("/chatter", data, 6)
    assert [(t, n, d) for t, _, n, d in BagReader(tmp_path / "b").messages()] == [("/chatter", 5, data)]
    with pytest.raises(FileExistsError):
        BagWriter(tmp_path / "b")


def test_empty_bag_is_readable(tmp_path):
    with BagWriter(tmp_path / "empty", storage_name="empty.mcap") as writer:
        writer.add_topic("/chatter", "std_msgs/msg/String")
    info = yaml.safe_load((tmp_path / "empty" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["message_count"] == 0 and info["relative_file_paths"] == ["empty.mcap"]
    with AnyReader([tmp_path / "empty"]) as reader:
        assert [(c.topic, c.msgcount) for c in reader.connections] == [("/chatter", 0)]
        assert list(reader.messages()) == []


CHILD = """
import signal, sys
from rclpy.serialization import serialize_message
from bench_msgs.msg import StepAck
from bench_engine.bag_writer import BagWriter

writer = BagWriter(sys.argv[1])
writer.add_topic("/sim/ack", "bench_msgs/msg/StepAck")

def stop(signum, frame):
    print(step, flush=True)  # write() calls that returned (one fewer if the signal came before step += 1)
    writer.close()
    sys.exit(0)

if sys.argv[2] == "signal":
    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
step = 0
while sys.argv[2] == "signal" or step < 500:
    writer.write("/sim/ack", serialize_message(StepAck(node="child", step=step, count=step)), 10**9 + step)
    step += 1
    if step == 300:
        print("ready", flush=True)
"""


def _run_child(directory: Path, mode: str) -> subprocess.Popen:
    env = dict(os.environ)
    src = str(Path(orbit_sim.__file__).resolve().parents[1])
    env["PYTHONPATH"] = os.pathsep.join(p for p in (src, env.get("PYTHONPATH")) if p)
    return subprocess.Popen(
        [sys.executable, "-c", CHILD, str(directory), mode],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _steps_read_by_rosbags(directory: Path) -> list[int]:
    with AnyReader([directory]) as reader:
        steps = [reader.deserialize(raw, c.msgtype).step for c, _, raw in reader.messages()]
        assert reader.message_count == len(steps)
    return steps


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_writer_closed_in_signal_handler_leaves_readable_bag(tmp_path, signum):
    child = _run_child(tmp_path / "sig_bag", "signal")
    try:
        assert child.stdout.readline().strip() == "ready"
        child.send_signal(signum)
        out, err = child.communicate(timeout=60)
    finally:
        child.kill()
    assert child.returncode == 0, err
    returned = int(out.split()[-1])
    steps = _steps_read_by_rosbags(tmp_path / "sig_bag")
    assert returned >= 300
    assert steps == list(range(len(steps)))
    assert returned <= len(steps) <= returned + 1  # every message whose write() returned is in the bag


def test_bag_is_finished_when_main_thread_ends_without_close(tmp_path):
    child = _run_child(tmp_path / "forgotten", "no_close")
    _, err = child.communicate(timeout=60)
    assert child.returncode == 0, err
    assert _steps_read_by_rosbags(tmp_path / "forgotten") == list(range(500))


class _FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def _flushed_steps(schedule: FlushSchedule, clock: _FakeClock, wall_per_step: float, steps: int) -> list[int]:
    flushed = []
    for k in range(1, steps + 1):
        clock.now += wall_per_step
        if schedule.due():
            flushed.append(k)
    return flushed


def test_a_slow_run_is_flushed_every_steps_steps() -> None:
    """Steps slower than the wall interval: a flush every ``steps`` steps, the first after ``steps``."""
    clock = _FakeClock()
    schedule = FlushSchedule(10, 0.5, clock)
    clock.now += 60.0  # recording started long before stepping
    assert _flushed_steps(schedule, clock, 0.2, 45) == [10, 20, 30, 40]


def test_a_fast_run_is_flushed_every_wall_interval() -> None:
    """A lock-step run of ~1 ms steps (2**-10 s: exact in binary), each its own sim second (steps=1): one flush
    per 0.5 s of wall time, not one per step (the first at the first step, recording having started earlier)."""
    clock = _FakeClock()
    schedule = FlushSchedule(1, 0.5, clock)
    clock.now += 5.0
    flushed = _flushed_steps(schedule, clock, 2.0**-10, 2000)
    assert flushed[0] == 1 and np.diff(flushed).tolist() == [512, 512, 512]


@pytest.mark.parametrize("steps, wall_s", [(0, 0.5), (1, -1.0), (1, float("nan"))])
def test_a_flush_schedule_refuses_bad_intervals(steps: int, wall_s: float) -> None:
    with pytest.raises(ValueError, match="FlushSchedule"):
        FlushSchedule(steps, wall_s)
