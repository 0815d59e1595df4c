"""Bags that survive a crash (bench_engine.recovery): what a killed recorder flushed is rebuilt into a complete
rosbag2 bag that the independent reader opens, with its sim-time log times and file order kept."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import yaml
from graph_helpers import read_bag, script
from mcap.opcode import Opcode
from mcap.reader import make_reader
from rclpy.serialization import serialize_message

from bench_engine.bag_errors import BagUnrecoverable
from bench_engine.bag_reader import BagReader
from bench_engine.bag_writer import BagWriter
from bench_engine.msg_schema import message_class
from bench_engine.recovery import needs_recovery, recover

TRUTH = "bench_msgs/msg/TruthState"


def truth(step: int) -> bytes:
    msg = message_class(TRUTH)()
    msg.step, msg.labels, msg.state = step, ["x"], [float(step)]
    return serialize_message(msg)


def last_chunk_offset(mcap: Path) -> int:
    """File offset of the last Chunk record."""
    data = mcap.read_bytes()
    offset, last = 8, -1  # after the magic: records are opcode (1 byte), length (8 bytes), content
    while offset + 9 <= len(data):
        if data[offset] == Opcode.CHUNK:
            last = offset
        offset += 9 + int.from_bytes(data[offset + 1 : offset + 9], "little")
    return last


def crashed_copy(tmp_path: Path, flushed: int, unflushed: int, cut_last_chunk: bool = False) -> Path:
    """A bag as a SIGKILLed recorder leaves it: ``flushed`` steps flushed, ``unflushed`` more written after the
    last flush, no close; with ``cut_last_chunk`` the file ends inside its last chunk (a record cut in half)."""
    writer = BagWriter(tmp_path / "live")
    writer.add_topic("/truth/state", TRUTH)
    for k in range(flushed):
        writer.write("/truth/state", truth(k), 1_000 + k)
        if k % 10 == 9:
            writer.flush()
    writer.flush(wait=True)  # the file holds every flushed message: what a crash would leave from here on
    for k in range(flushed, flushed + unflushed):
        writer.write("/truth/state", truth(k), 1_000 + k)  # into the chunk in progress, not the file
    crashed = tmp_path / "crashed"
    shutil.copytree(tmp_path / "live", crashed)
    if cut_last_chunk:
        mcap = next(crashed.glob("*.mcap"))
        mcap.write_bytes(mcap.read_bytes()[: last_chunk_offset(mcap) + 30])
    writer.close()
    return crashed


def steps_of(bag: Path) -> list[int]:
    return [m.step for _, m in read_bag(bag)["/truth/state"]]


def test_every_flushed_message_is_recovered_and_the_unflushed_are_lost(tmp_path: Path) -> None:
    bag = crashed_copy(tmp_path, flushed=35, unflushed=7)
    assert needs_recovery(bag)
    with pytest.raises(Exception):  # noqa: B017 - any error of the independent reader: its types are its own
        read_bag(bag)  # what the crash left: no reader opens it
    done = recover(bag)
    assert done.kept == {"/truth/state": 35} and done.truncated_file.is_file()
    assert steps_of(bag) == list(range(35))
    assert not needs_recovery(bag) and "recovered 35 messages" in done.summary()


def test_a_record_cut_in_half_ends_the_recovered_data_at_the_last_whole_chunk(tmp_path: Path) -> None:
    bag = crashed_copy(tmp_path, flushed=40, unflushed=0, cut_last_chunk=True)
    done = recover(bag)
    assert done.lost_bytes == 30
    assert steps_of(bag) == list(range(30))  # chunks of 10 steps: the cut one is lost whole


def test_the_reader_recovers_a_crashed_bag_itself(tmp_path: Path, capsys) -> None:
    bag = crashed_copy(tmp_path, flushed=12, unflushed=3)
    assert [t for t, *_ in BagReader(bag).messages()] == ["/truth/state"] * 12
    assert "recovered 12 messages" in capsys.readouterr().err


def _written_in_file_order(bag: Path) -> list[tuple[str, int, int, bytes]]:
    """(topic, log time, publish time, bytes) of every message, in file order."""
    with open(next(bag.glob("*.mcap")), "rb") as f:
        return [
            (c.topic, m.log_time, m.publish_time, m.data)
            for _, c, m in make_reader(f).iter_messages(log_time_order=False)
        ]


def test_sim_log_times_out_of_order_are_kept_with_the_file_order(tmp_path: Path) -> None:
    """A sim-time bag: the estimate of step k is written after the truth of step k + 3 (log times go back);
    the rebuilt bag keeps every flushed message where it was, with its log and publish times."""
    writer = BagWriter(tmp_path / "live")
    writer.add_topic("/truth/state", TRUTH)
    writer.add_topic("/ukf/estimate", TRUTH)
    written = []
    for k in range(40):
        for topic, step in [("/truth/state", k), ("/ukf/estimate", k - 3)][: 2 if k >= 3 else 1]:
            t_ns = 4_320_800_000_000 + step * 100_000_000
            written.append((topic, t_ns, t_ns - 7, truth(step)))
            writer.write(topic, truth(step), t_ns, t_ns - 7)
        if k % 10 == 9:
            writer.flush(wait=k == 39)
    shutil.copytree(tmp_path / "live", tmp_path / "crashed")
    writer.close()
    done = recover(tmp_path / "crashed")
    assert _written_in_file_order(tmp_path / "crashed") == written
    assert done.log_span_ns == (4_320_800_000_000, 4_324_700_000_000)
    assert "sim time 4320.8–4324.7 s" in done.summary()
    info = yaml.safe_load((tmp_path / "crashed" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["starting_time"] == {"nanoseconds_since_epoch": 4_320_800_000_000}
    assert info["duration"] == {"nanoseconds": 3_900_000_000}
    assert [t for t, _ in read_bag(tmp_path / "crashed")["/ukf/estimate"]] == [
        t for topic, t, _, _ in written if topic == "/ukf/estimate"
    ]


def test_a_forced_rebuild_keeps_the_custom_data(tmp_path: Path) -> None:
    with BagWriter(tmp_path / "bag", custom_data={"wall_clock_start_ns": "17"}) as writer:
        writer.add_topic("/truth/state", TRUTH)
        writer.write("/truth/state", truth(0), 5)
    metadata = tmp_path / "bag" / "metadata.yaml"
    metadata.write_text(metadata.read_text().replace("'17'", "17"))  # as yaml-cpp writes it: unquoted
    assert "wall_clock_start_ns: 17\n" in metadata.read_text()
    recover(tmp_path / "bag")
    info = yaml.safe_load(metadata.read_text())["rosbag2_bagfile_information"]
    assert info["custom_data"] == {"wall_clock_start_ns": "17"} and info["message_count"] == 1


def test_nothing_to_recover_is_a_clear_error(tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    with pytest.raises(BagUnrecoverable, match="no .mcap file"):
        recover(tmp_path / "empty")
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "junk_0.mcap").write_bytes(b"not an mcap file")
    with pytest.raises(BagUnrecoverable, match="not even the MCAP header"):
        recover(tmp_path / "junk")


def rechunked_copy(bag: Path, copy: Path, every: int) -> None:
    """``bag``'s messages and run config in a new bag ``copy`` whose chunks end every ``every`` messages, as a
    recorder of a slower run flushes them (a single-process run of a few hundred steps takes
    less wall time than a flush interval: bench_engine.bag_writer.FlushSchedule)."""
    reader = BagReader(bag)
    with BagWriter(copy) as writer:
        for topic, type_name in reader.topics().items():
            writer.add_topic(topic, type_name)
        for n, (topic, _, log_time, data) in enumerate(reader.messages()):
            writer.write(topic, data, log_time)
            if n % every == every - 1:
                writer.flush()
    shutil.copy(bag / "run_config.yaml", copy / "run_config.yaml")


def test_score_recovers_a_crashed_bag_and_names_what_it_cannot_read(tmp_path: Path) -> None:
    res = script(
        "launch.py",
        "formation_cqkf",
        "--set",
        "time.duration=120",
        "--no-score",
        "--single-process",
        "--out",
        str(tmp_path / "run"),
    )
    assert res.returncode == 0, res.stderr[-2000:]
    crashed = tmp_path / "crashed"
    rechunked_copy(tmp_path / "run" / "bag", crashed, every=20)
    (crashed / "metadata.yaml").unlink()  # what a SIGKILLed recorder leaves: no metadata, the file cut short
    mcap = next(crashed.glob("*.mcap"))
    mcap.write_bytes(mcap.read_bytes()[: mcap.stat().st_size * 3 // 5])
    res = script("score.py", str(crashed), "--json")
    assert res.returncode == 0, res.stderr[-2000:]
    assert "recovered" in res.stderr and json.loads(res.stdout)["estimators"]["ss"]["runs"] == 1
    (tmp_path / "empty").mkdir()
    res = script("score.py", str(tmp_path / "empty"))
    assert res.returncode == 2 and "not a bag directory" in res.stderr and "Traceback" not in res.stderr
    damaged = tmp_path / "damaged"
    shutil.copytree(tmp_path / "run" / "bag", damaged)
    mcap = next(damaged.glob("*.mcap"))
    mcap.write_bytes(mcap.read_bytes()[:-100])
    res = script("score.py", str(damaged))
    assert res.returncode == 2 and "recover_bag.py --force" in res.stderr and "Traceback" not in res.stderr
    res = script("recover_bag.py", "--force", str(damaged))
    assert res.returncode == 0 and "recovered" in res.stdout
    assert script("score.py", str(damaged)).returncode == 0
