"""Fuzzed bag readers (issue 18, item 2): damaged and hostile copies of real bags through every reader.

Readers: ``BagReader`` (topics, messages, payloads, tables, decoded), the columnar decoder
(``bench_engine.columns.table``), the CDR decoder (``bench_engine.cdr.deserialize``) and recovery
(``bench_engine.recovery.recover``). Inputs: a short leo_radar bag and a star_tracker one, recorded once per session
through the real graph, their LZ4, uncompressed and unchunked rewrites, and mutations of them: bit flips,
truncation (at every record boundary, and anywhere), inflated length fields, records given another opcode,
duplicated chunks, zeroed blocks, chunks claiming huge uncompressed sizes, damage inside chunks whose CRC is then
made to match again; CDR payloads with huge sequence counts and strings without their NUL; hand-made files for the
shapes a random mutation rarely hits.

Property of every example: the reader gives exactly what the undamaged bag gives (CRCs make damage visible), or
raises its own error (``bench_engine.bag_errors.BagError``, one line naming the bag; ``cdr.deserialize``:
``ValueError``, its documented error) -- nothing else -- within ``TIME_LIMIT_S``, and with at most
``ADDRESS_HEADROOM`` more address space than the process had (RLIMIT_AS lowered for the example: a larger
allocation, by Python or by zstd, lz4 or rclpy's C code, fails with a MemoryError, which is no reader's error).
Recovery keeps exactly the messages of a prefix of whole chunks of the file. The hand-made hostile files are also
read under tracemalloc (at most ``MEMORY_LIMIT`` allocated: a chunk claiming 2^40 bytes is refused before any
allocation) and in a subprocess capped at 768 MiB of address space above its imports; the streaming test measures
recovery's peak on a 48 MiB bag.

Budget: CI runs ``BENCH_FUZZ_EXAMPLES`` examples per reader and bag (default 40; recovery a quarter, as each
example writes a bag; the same examples every run: derandomised); a larger campaign draws fresh random examples,
and rebuilds a bag at every record boundary::

    BENCH_FUZZ_EXAMPLES=2000 .venv/bin/python -m pytest tests/test_fuzz_readers.py

(``BENCH_FUZZ_SEED=N`` repeats a campaign.) ``BENCH_FUZZ_SCORE=N`` also runs N damaged copies of the leo_radar bag
through ``scripts/score.py`` (one line on stderr, non-zero exit, no traceback); CI runs 4.
"""

from __future__ import annotations

import array
import contextlib
import functools
import io
import json
import os
import random
import resource
import shutil
import signal
import struct
import subprocess
import sys
import time
import tracemalloc
import zlib
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import lz4.frame
import numpy as np
import pytest
import zstandard
from graph_helpers import script
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.data_stream import ReadDataStream
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, Message
from mcap.stream_reader import breakup_chunk
from mcap.writer import CompressionType, Writer

import bench_engine.mcap_records as bag_module
from bench_engine import cdr
from bench_engine.bag_errors import BagDamaged, BagError, BagUnrecoverable, BagUnsupported, MessageDamaged
from bench_engine.bag_reader import BagReader
from bench_engine.bag_writer import BagWriter
from bench_engine.columns import NoColumnarLayout, table
from bench_engine.mcap_records import MAX_CHUNK_BYTES, RecordScan
from bench_engine.recovery import recover

EXAMPLES = int(os.environ.get("BENCH_FUZZ_EXAMPLES", "40"))
CAMPAIGN = "BENCH_FUZZ_EXAMPLES" in os.environ
SCORE_COPIES = int(os.environ.get("BENCH_FUZZ_SCORE", "4"))
TIME_LIMIT_S = 20.0  # per example: a hang, not a slow machine (CI shares 2 cores)
ADDRESS_HEADROOM = 256 << 20  # address space an example may map beyond what the process had (RLIMIT_AS)
MEMORY_LIMIT = 64 << 20  # bytes a traced example may allocate beyond what was held (tracemalloc peak)
MAGIC = b"\x89MCAP0\r\n"

FUZZ = settings(
    max_examples=EXAMPLES,
    deadline=None,
    database=None,
    derandomize=not CAMPAIGN,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.function_scoped_fixture],
)
FUZZ_RECOVERY = settings(FUZZ, max_examples=max(8, EXAMPLES // 4))  # each example writes a bag
if CAMPAIGN and "BENCH_FUZZ_SEED" in os.environ:
    from hypothesis import seed as _seed

    FUZZ_SEED = _seed(int(os.environ["BENCH_FUZZ_SEED"]))
else:

    def FUZZ_SEED(f):  # noqa: N802 - a no-op decorator in place of hypothesis.seed
        return f


# --- bounds on every example ---------------------------------------------------------------------------------


class Hang(Exception):
    """An example ran past TIME_LIMIT_S."""


def _mapped() -> int:
    """This process's address space now (VmSize), in bytes."""
    with open("/proc/self/status") as f:
        return int(next(line for line in f if line.startswith("VmSize")).split()[1]) * 1024


@contextlib.contextmanager
def bounded(what: str):
    """Run one example within bounds: at most TIME_LIMIT_S seconds (SIGALRM, then the wall time checked); at most
    ADDRESS_HEADROOM bytes of address space more than the process had mapped when it started (RLIMIT_AS, lowered
    for the example: anything larger fails with a MemoryError, which is no reader's error, C allocations
    included); and, when tracemalloc is tracing (the ``traced`` fixture), at most MEMORY_LIMIT bytes allocated
    beyond what was held when it started."""

    def on_alarm(signum, frame):
        raise Hang(f"{what}: still running after {TIME_LIMIT_S} s")

    previous = signal.signal(signal.SIGALRM, on_alarm)
    signal.setitimer(signal.ITIMER_REAL, TIME_LIMIT_S)
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    cap = _mapped() + ADDRESS_HEADROOM
    resource.setrlimit(resource.RLIMIT_AS, (cap if hard == resource.RLIM_INFINITY else min(cap, hard), hard))
    traced = tracemalloc.is_tracing()
    held = tracemalloc.get_traced_memory()[0] if traced else 0
    tracemalloc.reset_peak()
    start = time.monotonic()
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    elapsed = time.monotonic() - start
    assert elapsed < TIME_LIMIT_S, f"{what}: {elapsed:.1f} s"
    if traced:
        peak = tracemalloc.get_traced_memory()[1] - held
        assert peak < MEMORY_LIMIT, f"{what}: allocated {peak / 2**20:.1f} MiB"


@pytest.fixture
def traced():
    tracemalloc.start()
    yield
    tracemalloc.stop()


def own_error(err: BaseException, bag: Path) -> None:
    """A reader's error: one line naming the bag."""
    assert isinstance(err, BagError), f"{type(err).__name__}: {err}"
    assert "\n" not in str(err) and str(bag) in str(err), str(err)


# --- real bags, their layout and what the readers give for them -------------------------------------------------


@dataclass
class Layout:
    """Where an intact MCAP file's records are: (offset, opcode, length) of each top-level record up to the footer,
    the chunk records among them, the chunk index records of the summary, the summary's start."""

    data: bytes
    records: list[tuple[int, int, int]]
    chunks: list[tuple[int, int]]  # (offset, length of the body)
    chunk_indexes: list[tuple[int, int]]
    summary_start: int
    footer: int

    @classmethod
    def of(cls, data: bytes) -> Layout:
        records, pos = [], 8
        while True:
            opcode, length = data[pos], struct.unpack_from("<Q", data, pos + 1)[0]
            records.append((pos, opcode, length))
            if opcode == 0x02:
                break
            pos += 9 + length
        footer = records[-1][0]
        summary_start = struct.unpack_from("<Q", data, footer + 9)[0]
        return cls(
            data,
            records,
            [(o, n) for o, op, n in records if op == 0x06],
            [(o, n) for o, op, n in records if op == 0x08],
            summary_start,
            footer,
        )

    def chunk_messages(self) -> list[list[tuple[str, int, int, bytes]]]:
        """Per chunk, in file order: (topic, log time, publish time, data) of its messages (mcap's own reader)."""
        channels = make_reader(io.BytesIO(self.data)).get_summary().channels
        out = []
        for offset, length in self.chunks:
            chunk = Chunk.read(ReadDataStream(io.BytesIO(self.data[offset + 9 : offset + 9 + length])))
            out.append(
                [
                    (channels[r.channel_id].topic, r.log_time, r.publish_time, r.data)
                    for r in breakup_chunk(chunk)
                    if isinstance(r, Message)
                ]
            )
        return out


def rewrite(src: Path, dst: Path, compression: CompressionType, chunked: bool = True) -> None:
    """A copy of bag ``src`` whose MCAP file is written again by mcap's writer with ``compression`` and chunks of
    16 KiB (more chunks than the recorder's 768 KiB make in a short run), or no chunks (messages in the data
    section, no chunk index: the reader reads it from the start); same messages in the same order, same
    metadata.yaml."""
    dst.mkdir(parents=True)
    for f in src.iterdir():
        if f.suffix != ".mcap":
            shutil.copy(f, dst / f.name)
    mcap = next(src.glob("*.mcap"))
    with open(mcap, "rb") as fin, open(dst / mcap.name, "wb") as fout:
        writer = Writer(fout, chunk_size=16 * 1024, compression=compression, use_chunking=chunked)
        writer.start(profile="ros2", library="test_fuzz_readers")
        schemas, channels = {}, {}
        for schema, channel, message in make_reader(fin).iter_messages(log_time_order=False):
            if schema.id not in schemas:
                schemas[schema.id] = writer.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channels:
                channels[channel.id] = writer.register_channel(
                    channel.topic, channel.message_encoding, schemas[schema.id], channel.metadata
                )
            writer.add_message(
                channels[channel.id], message.log_time, message.data, message.publish_time, message.sequence
            )
        writer.finish()


@dataclass
class Bag:
    """One intact bag directory, its MCAP file's layout, and what every reader gives for it. ``sample``: one
    topic of each type that has messages, the one with fewest (what ``tables`` and ``decoded`` read in the
    examples: those decoders' cost is per message, and their input is what ``payloads`` and ``messages`` gave);
    ``columnar``: those of them the columnar decoder covers."""

    name: str
    directory: Path
    layout: Layout
    topics: dict[str, str]
    sample: list[str]
    columnar: list[str]
    reference: dict[str, Any]
    chunks: list[list[tuple[str, int, int, bytes]]]

    @classmethod
    def of(cls, name: str, directory: Path) -> Bag:
        layout = Layout.of(next(directory.glob("*.mcap")).read_bytes())
        reader = BagReader(directory, recover=False)
        topics = reader.topics()
        payloads = reader.payloads(topics)
        fewest: dict[str, str] = {}
        for topic in sorted(payloads, key=lambda t: (len(payloads[t]), t)):
            fewest.setdefault(topics[topic], topic)
        sample = sorted(fewest.values())
        columnar = []
        for topic in sample:
            try:
                table(topics[topic], payloads[topic][:1])
                columnar.append(topic)
            except NoColumnarLayout:
                pass
        reference = read_all(directory, list(topics), sample, columnar)
        assert not any(isinstance(v, BaseException) for v in reference.values()), reference
        return cls(name, directory, layout, topics, sample, columnar, reference, layout.chunk_messages())

    @property
    def mcap_name(self) -> str:
        return next(self.directory.glob("*.mcap")).name


def read_all(directory: Path, topics: list[str], sample: list[str], columnar: list[str]) -> dict[str, Any]:
    """What each BagReader method gives for a bag directory (the error, if it raises one of the reader's own)."""
    reader = BagReader(directory, recover=False)
    calls: dict[str, Callable[[], Any]] = {
        "topics": reader.topics,
        "messages": lambda: list(reader.messages()),
        "payloads": lambda: reader.payloads(topics),
        "tables": lambda: reader.tables(columnar),
        "decoded": lambda: list(reader.decoded(sample)),
    }
    out = {}
    for name, call in calls.items():
        try:
            out[name] = call()
        except BagError as err:
            out[name] = err
    return out


def equal(a: Any, b: Any) -> bool:
    """Equal values, NaN equal to NaN: numbers, arrays, lists, rclpy messages field by field."""
    if hasattr(a, "get_fields_and_field_types"):
        return type(a) is type(b) and all(equal(getattr(a, f), getattr(b, f)) for f in a.get_fields_and_field_types())
    if isinstance(a, (np.ndarray, array.array)) or isinstance(b, (np.ndarray, array.array)):
        x, y = np.asarray(a), np.asarray(b)
        return x.shape == y.shape and np.array_equal(x, y, equal_nan=x.dtype.kind == "f" and y.dtype.kind == "f")
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(equal(u, v) for u, v in zip(a, b))
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (a != a and b != b)
    return a == b


def same(name: str, got: Any, want: Any) -> bool:
    if name != "tables":
        return equal(got, want)
    return got.keys() == want.keys() and all(
        got[t].columns.keys() == want[t].columns.keys()
        and all(equal(got[t].columns[c], want[t].columns[c]) for c in got[t].columns)
        for t in got
    )


@pytest.fixture(scope="session")
def recorded(tmp_path_factory) -> dict[str, Path]:
    """A 10 s leo_radar run and a 1 s star_tracker run through the graph (one process), recorded once."""
    out = {}
    for name, scenario, duration in (("leo", "leo_radar", "10"), ("star", "star_tracker", "1")):
        run = tmp_path_factory.mktemp(f"fuzz_{name}")
        res = script(
            "launch.py",
            scenario,
            "--set",
            f"time.duration={duration}",
            "--single-process",
            "--no-score",
            "--out",
            str(run / "run"),
        )
        assert res.returncode == 0, res.stderr[-2000:]
        out[name] = run / "run" / "bag"
    return out


@pytest.fixture(scope="session")
def bags(recorded, tmp_path_factory) -> dict[str, Bag]:
    """The recorded bags (zstd, as the recorder writes them) and the leo_radar one rewritten with LZ4, without
    compression, and without chunks; what the reader gives for each is checked against mcap's own reader."""
    out = {"leo": Bag.of("leo", recorded["leo"]), "star": Bag.of("star", recorded["star"])}
    for name, compression, chunked in (
        ("leo_lz4", CompressionType.LZ4, True),
        ("leo_none", CompressionType.NONE, True),
        ("leo_unchunked", CompressionType.NONE, False),
    ):
        directory = tmp_path_factory.mktemp(f"fuzz_{name}") / "bag"
        rewrite(recorded["leo"], directory, compression, chunked)
        out[name] = Bag.of(name, directory)
    for bag in out.values():  # the reader's order is mcap's; its payloads, mcap's in file order
        with open(next(bag.directory.glob("*.mcap")), "rb") as f:
            assert bag.reference["messages"] == [
                (c.topic, s.name, m.log_time, m.data) for s, c, m in make_reader(f).iter_messages()
            ], bag.name
            f.seek(0)
            in_file_order: dict[str, list[bytes]] = {}
            for _, c, m in make_reader(f).iter_messages(log_time_order=False):
                in_file_order.setdefault(c.topic, []).append(m.data)
            assert bag.reference["payloads"] == in_file_order, bag.name
        assert bag.reference["messages"] == out[bag.name.split("_")[0]].reference["messages"], bag.name
    return out


# --- mutations -------------------------------------------------------------------------------------------------

HUGE = [2**32 - 1, 2**40, 2**63, 2**64 - 1, MAX_CHUNK_BYTES, MAX_CHUNK_BYTES + 1, 512 << 20]


@st.composite
def mutation(draw, layout: Layout, inner: bool = False) -> tuple:
    """One mutation of a file with ``layout`` (a tuple, so hypothesis shows and shrinks it)."""
    n = len(layout.data)
    kinds = (
        ["flip", "cut", "inflate", "zero", "opcode"]
        + (["chunk_field", "dup", "claim"] if layout.chunks else [])
        + (["inner"] * 4 if inner else [])
    )
    kind = draw(st.sampled_from(kinds))
    if kind == "flip":
        return kind, draw(st.integers(0, n - 1)), draw(st.integers(0, 7))
    if kind == "cut":
        boundary = draw(st.sampled_from([o for o, _, _ in layout.records] + [n - 8]))
        return kind, max(0, boundary + draw(st.sampled_from([0, 0, 0, 1, 8, 9, 30, -1])))
    if kind == "inflate":
        return kind, draw(st.integers(0, len(layout.records) - 1)), draw(st.sampled_from([1, 7, 9, 4096, *HUGE]))
    if kind == "opcode":  # a record made another (a chunk a message index, a footer, a private record, ...)
        return kind, draw(st.integers(0, len(layout.records) - 1)), draw(st.integers(0, 255))
    if kind == "chunk_field":  # the chunk's own compressed length (u64) or compression name length (u32)
        return (
            kind,
            draw(st.integers(0, len(layout.chunks) - 1)),
            draw(st.sampled_from(["data", "name"])),
            draw(st.sampled_from([1, 9, 2**20, 2**31, 2**32 - 1, 2**40, 2**64 - 1])),
        )
    if kind == "dup":
        return kind, draw(st.integers(0, len(layout.chunks) - 1))
    if kind == "zero":
        return kind, draw(st.integers(0, n - 1)), draw(st.integers(1, 4096))
    if kind == "claim":  # the chunk's uncompressed size, also in its index (then the summary CRC is zeroed)
        actual = struct.unpack_from("<Q", layout.data, layout.chunks[0][0] + 9 + 16)[0]
        return (
            kind,
            draw(st.integers(0, len(layout.chunks) - 1)),
            draw(st.sampled_from([0, 1, actual - 1, actual + 1, 2 * actual, *HUGE])),
            draw(st.booleans()),
        )
    # inside a chunk's records (an uncompressed file), then its CRC made to match again
    chunk = draw(st.integers(0, len(layout.chunks) - 1))
    op = draw(st.sampled_from(["flip", "zero", "u32", "u64"]))
    value = draw(st.sampled_from([0, 1, 0xFFFFFFFF, 2**31, 2**40, 2**64 - 1]))
    return "inner", chunk, op, draw(st.integers(0, 10**6)), value


def mutations(layout: Layout, inner: bool = False):
    return st.lists(mutation(layout, inner), min_size=1, max_size=3)


def apply(layout: Layout, muts: list[tuple]) -> bytes:
    """The file with ``muts`` applied in turn (each placed on the original layout; later ones clipped to the
    file as it is by then)."""
    data = bytearray(layout.data)
    for m in muts:
        kind = m[0]
        if kind == "flip":
            if m[1] < len(data):
                data[m[1]] ^= 1 << m[2]
        elif kind == "cut":
            del data[m[1] :]
        elif kind == "opcode":
            if layout.records[m[1]][0] < len(data):
                data[layout.records[m[1]][0]] = m[2]
        elif kind == "inflate":
            offset = layout.records[m[1]][0] + 1
            if offset + 8 <= len(data):
                value = struct.unpack_from("<Q", data, offset)[0]
                struct.pack_into("<Q", data, offset, (value + m[2]) % 2**64)
        elif kind == "chunk_field":
            offset, _ = layout.chunks[m[1]]
            name_length = struct.unpack_from("<I", layout.data, offset + 9 + 28)[0]
            at, fmt = (offset + 9 + 32 + name_length, "<Q") if m[2] == "data" else (offset + 9 + 28, "<I")
            if at + struct.calcsize(fmt) <= len(data):
                value = struct.unpack_from(fmt, data, at)[0]
                struct.pack_into(fmt, data, at, (value + m[3]) % 2 ** (8 * struct.calcsize(fmt)))
        elif kind == "dup":
            offset, length = layout.chunks[m[1]]
            record = layout.data[offset : offset + 9 + length]
            data[offset + 9 + length : offset + 9 + length] = record
        elif kind == "zero":
            data[m[1] : m[1] + m[2]] = bytes(len(data[m[1] : m[1] + m[2]]))
        elif kind == "claim":
            offset, _ = layout.chunks[m[1]]
            if offset + 9 + 24 <= len(data):
                struct.pack_into("<Q", data, offset + 9 + 16, m[2] % 2**64)
            index_offset, index_length = layout.chunk_indexes[m[1]]
            end = index_offset + 9 + index_length
            if m[3] and end <= len(data):
                struct.pack_into("<Q", data, end - 8, m[2] % 2**64)
                if layout.footer + 29 <= len(data):
                    struct.pack_into("<I", data, layout.footer + 25, 0)  # summary CRC: not computed
        elif kind == "inner":
            _, chunk, op, pos, value = m
            offset, length = layout.chunks[chunk]
            start = offset + 9 + 32 + 8  # no compression name: an uncompressed file
            end = offset + 9 + length
            if end > len(data) or end - start < 8:
                continue
            at = start + pos % (end - start - 8)
            if op == "flip":
                data[at] ^= 1 << (value % 8)
            elif op == "zero":
                data[at : at + 8] = bytes(8)
            elif op == "u32":
                struct.pack_into("<I", data, at, value % 2**32)
            else:
                struct.pack_into("<Q", data, at, value % 2**64)
            struct.pack_into("<I", data, offset + 9 + 24, zlib.crc32(data[start:end]))
    return bytes(data)


def with_file(bag: Bag, work: Path, data: bytes, metadata: bool = True) -> Path:
    """A fresh bag directory in ``work`` holding ``data`` as the bag's MCAP file (and its metadata.yaml)."""
    directory = work / "bag"
    shutil.rmtree(directory, ignore_errors=True)
    shutil.rmtree(work / "bag.recovering", ignore_errors=True)
    directory.mkdir(parents=True)
    (directory / bag.mcap_name).write_bytes(data)
    if metadata:
        shutil.copy(bag.directory / "metadata.yaml", directory / "metadata.yaml")
    return directory


# --- the bag reader -------------------------------------------------------------------------------------------


def check_reader(bag: Bag, directory: Path, what: str, intact: bool = True) -> dict[str, Any]:
    """Every BagReader method on ``directory``: the undamaged bag's result (``intact``) or the reader's own error."""
    with bounded(what):
        got = read_all(directory, list(bag.topics), bag.sample, bag.columnar)
    for name, value in got.items():
        if isinstance(value, BaseException):
            own_error(value, directory)
        elif intact:
            assert same(name, value, bag.reference[name]), f"{what}: {name} differs from the undamaged bag's"
    return got


@pytest.mark.parametrize("which", ["leo", "leo_lz4", "leo_none", "leo_unchunked", "star"])
def test_bag_reader_reads_what_is_intact_or_refuses(bags, which, tmp_path):
    """Mutated copies of a bag (metadata.yaml intact): each read gives what the undamaged bag gives or raises the
    reader's own error. A file without chunks has no CRC over its messages (mcap's writer leaves the data
    section's out): there a flipped bit in a message reads as another value, and only the errors are checked."""
    bag = bags[which]

    @FUZZ_SEED
    @FUZZ
    @given(muts=mutations(bag.layout))
    def check(muts):
        directory = with_file(bag, tmp_path, apply(bag.layout, muts))
        check_reader(bag, directory, f"{which} {muts}", intact=which != "leo_unchunked")

    check()


def test_bag_reader_inside_chunks_whose_crc_matches(bags, tmp_path):
    """Damage inside the records of an uncompressed chunk, its CRC made to match: the record walker and the CDR
    decoders see it. What reads is not necessarily what was recorded (the CRC vouches for it), but nothing
    escapes the reader's errors, hangs or allocates beyond the bound."""
    bag = bags["leo_none"]

    @FUZZ_SEED
    @FUZZ
    @given(muts=st.lists(mutation(bag.layout, inner=True).filter(lambda m: m[0] == "inner"), min_size=1, max_size=3))
    def check(muts):
        directory = with_file(bag, tmp_path, apply(bag.layout, muts))
        check_reader(bag, directory, f"inner {muts}", intact=False)

    check()


def test_truncation_at_every_record_boundary(bags, tmp_path):
    """Cut at each record boundary: the reader refuses the copy with its own error (every read starts with the
    summary, which a cut file has lost); recovery's scan reads exactly the messages of the chunks before the cut,
    and says where the whole records end. Recovery itself rebuilds a bag at every chunk's end and at a few other
    boundaries (at every boundary in a campaign)."""
    bag = bags["leo"]
    cuts = [o for o, _, _ in bag.layout.records] + [len(bag.layout.data) - 8]
    ends = sorted(o + 9 + n for o, n in bag.layout.chunks)
    rebuild = set(cuts) if CAMPAIGN else set(ends) | set(random.Random(18).sample(cuts, 4))
    for cut in cuts:
        data = bag.layout.data[:cut]
        kept = sum(1 for o, n in bag.layout.chunks if o + 9 + n <= cut)
        expected = [m for chunk in bag.chunks[:kept] for m in chunk]
        good = min(
            bag.layout.summary_start,  # the scan ends at DataEnd, where the summary starts
            max([8] + [o + 9 + n for o, _, n in bag.layout.records if o + 9 + n <= cut]),
        )
        directory = with_file(bag, tmp_path, data)
        with bounded(f"cut at {cut}"), pytest.raises(BagDamaged) as refused:  # every read starts at the summary
            BagReader(directory, recover=False).topics()
        own_error(refused.value, directory)
        mcap = directory / bag.mcap_name
        scan = RecordScan(mcap)
        with bounded(f"scan cut at {cut}"):
            messages = list(scan_messages(scan))
        assert messages == expected and scan.good == good, cut
        assert scan.complete == (cut >= bag.layout.summary_start), cut
        if cut in rebuild:
            directory = with_file(bag, tmp_path, data, metadata=False)
            with bounded(f"recover cut at {cut}"):
                done = recover(directory)
            assert rebuilt(directory) == expected, cut
            assert done.lost_bytes == (0 if scan.complete else cut - good), cut
    directory = with_file(bag, tmp_path, bag.layout.data[:7], metadata=False)
    with pytest.raises(BagUnrecoverable, match="not even the MCAP header"):
        recover(directory)


def scan_messages(scan: RecordScan):
    """(topic, log time, publish time, data) of each message a RecordScan reads, until it stops (at damage too)."""
    topics: dict[int, str] = {}
    try:
        for records in scan:
            for r in records:
                if isinstance(r, Channel):
                    topics[r.id] = r.topic
                elif isinstance(r, Message):
                    yield topics[r.channel_id], r.log_time, r.publish_time, r.data
    except BagDamaged:
        return


def test_the_reader_limits_refuse_before_reading(bags, monkeypatch):
    """The sane bounds the reader holds every file to (bench_engine.mcap_records: MAX_SUMMARY_BYTES, MAX_RECORD_BYTES,
    MAX_CHUNK_BYTES), lowered below what the leo_radar bag needs: each read is refused, naming the limit."""
    bag = bags["leo"]
    for limit, read in (
        ("MAX_SUMMARY_BYTES", lambda r: r.topics()),
        ("MAX_RECORD_BYTES", lambda r: r.payloads(list(bag.topics))),
        ("MAX_CHUNK_BYTES", lambda r: r.payloads(list(bag.topics))),
        ("MAX_RECORD_BYTES", lambda r: list(RecordScan(next(bag.directory.glob("*.mcap"))))),
    ):
        with monkeypatch.context() as patch:
            patch.setattr(bag_module, limit, 1000)
            with pytest.raises(BagDamaged, match=f"bench_engine.mcap_records.{limit}"):
                read(BagReader(bag.directory, recover=False))


# --- recovery ---------------------------------------------------------------------------------------------------


def rebuilt(directory: Path) -> list[tuple[str, int, int, bytes]]:
    """(topic, log time, publish time, data) of a rebuilt bag's messages in file order (mcap's own reader)."""
    with open(next(directory.glob("*.mcap")), "rb") as f:
        return [
            (c.topic, m.log_time, m.publish_time, m.data)
            for _, c, m in make_reader(f).iter_messages(log_time_order=False)
        ]


@pytest.mark.parametrize("which", ["leo", "leo_lz4", "star"])
def test_recovery_keeps_whole_chunks_or_refuses(bags, which, tmp_path):
    """A killed recorder's file (no metadata.yaml), damaged: recovery rebuilds a bag of the messages of a prefix of
    whole chunks of the file (with a duplicated chunk, of the file with that chunk twice), or raises its own
    error (BagUnrecoverable only when not even the magic is there)."""
    bag = bags[which]

    @FUZZ_SEED
    @FUZZ_RECOVERY
    @given(muts=mutations(bag.layout))
    def check(muts):
        directory = with_file(bag, tmp_path, apply(bag.layout, muts), metadata=False)
        chunks = list(bag.chunks)
        for m in muts:
            if m[0] == "dup":
                chunks.insert(m[1] + 1, bag.chunks[m[1]])
                break  # a second mutation places its chunk on the original layout: only the first is modelled
        with bounded(f"recover {which} {muts}"):
            try:
                done = recover(directory)
            except BagError as err:
                own_error(err, directory)
                return
            got = rebuilt(directory)
            by_topic: dict[str, list[bytes]] = {}
            for topic, _, _, data in got:
                by_topic.setdefault(topic, []).append(data)
            assert BagReader(directory, recover=False).payloads(list(bag.topics)) == by_topic
        if sum(m[0] == "dup" for m in muts) <= 1:
            prefixes = [[m for chunk in chunks[:k] for m in chunk] for k in range(len(chunks) + 1)]
            assert got in prefixes, f"{muts}: {len(got)} messages, not a prefix of whole chunks"
        assert sum(done.kept.values()) == len(got)

    check()


def test_recovery_streams_a_large_bag(tmp_path, traced):
    """Recovery holds about one chunk of the old file and a few of the new one, whatever the size of the bag:
    rebuilding a bag of 48 MiB of messages allocates a small fraction of that (tracemalloc peak)."""
    directory = tmp_path / "big"
    rng = np.random.default_rng(18)
    blob = rng.integers(0, 256, 16 << 20, dtype=np.uint8).tobytes()  # incompressible: the file is as large
    total, sizes = 0, []
    with BagWriter(directory) as writer:
        writer.add_topic("/truth/state", "bench_msgs/msg/TruthState")
        writer.add_topic("/ukf/estimate", "bench_msgs/msg/StateEstimate")
        k = 0
        while total < 48 << 20:
            size = int(rng.integers(1_000, 40_000))
            start = int(rng.integers(0, len(blob) - size))
            writer.write("/truth/state" if k % 3 else "/ukf/estimate", blob[start : start + size], 1_000 + k)
            total += size
            sizes.append(size)
            k += 1
            if k % 200 == 0:
                writer.flush(wait=True)
    del blob
    (directory / "metadata.yaml").unlink()  # what a killed recorder leaves (here with the summary: read to DataEnd)
    held = tracemalloc.get_traced_memory()[0]
    tracemalloc.reset_peak()
    done = recover(directory)
    peak = tracemalloc.get_traced_memory()[1] - held
    print(f"recovery of {total / 2**20:.0f} MiB of messages: peak {peak / 2**20:.1f} MiB allocated")
    assert sum(done.kept.values()) == len(sizes)
    assert peak < 12 << 20, f"recovery of {total >> 20} MiB allocated {peak / 2**20:.1f} MiB"
    assert [len(m[3]) for m in rebuilt(directory)] == sizes


# --- the columnar and CDR decoders --------------------------------------------------------------------------------


@st.composite
def payload_mutation(draw, length: int) -> tuple:
    kind = draw(st.sampled_from(["flip", "cut", "u32", "nul", "grow"]))
    if kind == "flip":
        return kind, draw(st.integers(0, length - 1)), draw(st.integers(0, 7))
    if kind == "cut":
        return kind, draw(st.integers(0, length - 1))
    if kind == "u32":  # a count or string length (4-aligned after the 4-byte encapsulation)
        return (
            kind,
            4 * draw(st.integers(0, max(0, length // 4 - 1))),
            draw(st.sampled_from([0, 1, 2, 3, 7, 0x7FFFFFFF, 0xFFFFFFFF, 0x10000, length, length + 1])),
        )
    if kind == "nul":  # the first NUL at or after a position: a string loses its terminator
        return kind, draw(st.integers(0, length - 1))
    return kind, draw(st.integers(1, 64))


def apply_payload(data: bytes, m: tuple) -> bytes:
    b = bytearray(data)
    if m[0] == "flip":
        b[m[1] % len(b)] ^= 1 << m[2]
    elif m[0] == "cut":
        del b[m[1] :]
    elif m[0] == "u32":
        if m[1] + 4 <= len(b):
            struct.pack_into("<I", b, m[1], m[2])
    elif m[0] == "nul":
        at = data.find(b"\x00", 4 + m[1] % max(1, len(b) - 4))
        if at >= 0:
            b[at] = 0x41
    else:
        b += bytes(m[1])
    return bytes(b)


def decoder_inputs(bags) -> list[tuple[str, str]]:
    return [(name, topic) for name in ("leo", "star") for topic in sorted(bags[name].topics)]


@pytest.mark.parametrize("which", ["leo", "star"])
def test_columnar_and_cdr_decoders_on_mutated_payloads(bags, which):
    """Real payloads of every topic, mutated: ``columns.table`` gives a table of every message or raises
    MessageDamaged (NoColumnarLayout for the types it does not cover); ``cdr.deserialize`` gives a message or
    raises ValueError. Where both read a message, they agree on every number and string."""
    bag = bags[which]
    payloads = BagReader(bag.directory, recover=False).payloads(list(bag.topics))
    topics = sorted(payloads)

    @FUZZ_SEED
    @FUZZ
    @given(data=st.data())
    def check(data):
        topic = data.draw(st.sampled_from(topics))
        type_name, originals = bag.topics[topic], payloads[topic]
        i = data.draw(st.integers(0, len(originals) - 1))
        muts = data.draw(st.lists(payload_mutation(len(originals[i])), min_size=1, max_size=3))
        mutated = originals[i]
        for m in muts:
            mutated = apply_payload(mutated, m) if mutated else mutated
        rows = [originals[(i + 1) % len(originals)], mutated, originals[i]]
        what = f"{topic} message {i} {muts}"
        with bounded(what):
            try:
                tab = table(type_name, rows)
            except MessageDamaged as err:
                assert "\n" not in str(err) and type_name in str(err)
                tab = None
            except NoColumnarLayout:
                assert topic not in bag.columnar
                tab = None
            except BagUnsupported as err:  # the encapsulation flipped to big-endian CDR
                assert "big-endian" in str(err)
                tab = None
            try:
                message = cdr.deserialize(type_name, mutated)
            except ValueError as err:
                assert "\n" not in str(err)
                message = None
        if tab is not None:
            assert len(tab) == 3
            if message is not None:
                assert_agrees(tab.row(1), message, what)

    check()


def assert_agrees(row: Any, message: Any, what: str, path: str = "") -> None:
    """A table row and a decoded message hold the same values (numbers bit for bit, NaN where NaN)."""
    for name, value in vars(row).items():
        other, where = getattr(message, name), f"{what}: {path}{name}"
        if isinstance(value, SimpleNamespace):
            assert_agrees(value, other, what, f"{path}{name}.")
        elif isinstance(value, str):
            assert value == other, where
        elif isinstance(value, (tuple, list)) and value and isinstance(value[0], str):
            assert list(value) == list(other), where
        else:
            x, y = np.asarray(value).reshape(-1), np.asarray(other).reshape(-1)
            assert x.size == y.size and np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), where


# --- hand-made hostile files ----------------------------------------------------------------------------------


def _rec(opcode: int, body: bytes) -> bytes:
    return bytes([opcode]) + struct.pack("<Q", len(body)) + body


def _str(text: str | bytes) -> bytes:
    raw = text.encode() if isinstance(text, str) else text
    return struct.pack("<I", len(raw)) + raw


def _xxh32(data: bytes, seed: int = 0) -> int:
    """xxHash32 (what an LZ4 frame header's checksum byte is taken from)."""
    p1, p2, p3, p4, p5 = 2654435761, 2246822519, 3266489917, 668265263, 374761393
    mask = 0xFFFFFFFF

    def rotl(x, r):
        return ((x << r) | (x >> (32 - r))) & mask

    n, i = len(data), 0
    if n >= 16:
        v = [(seed + p1 + p2) & mask, (seed + p2) & mask, seed, (seed - p1) & mask]
        while i + 16 <= n:
            for j in range(4):
                v[j] = (rotl((v[j] + struct.unpack_from("<I", data, i + 4 * j)[0] * p2) & mask, 13) * p1) & mask
            i += 16
        h = (rotl(v[0], 1) + rotl(v[1], 7) + rotl(v[2], 12) + rotl(v[3], 18)) & mask
    else:
        h = (seed + p5) & mask
    h = (h + n) & mask
    while i + 4 <= n:
        h = (rotl((h + struct.unpack_from("<I", data, i)[0] * p3) & mask, 17) * p4) & mask
        i += 4
    while i < n:
        h = (rotl((h + data[i] * p5) & mask, 11) * p1) & mask
        i += 1
    h ^= h >> 15
    h = (h * p2) & mask
    h ^= h >> 13
    h = (h * p3) & mask
    return h ^ (h >> 16)


def _lz4_claiming(raw: bytes, content_size: int) -> bytes:
    """An LZ4 frame of ``raw`` whose header claims ``content_size`` bytes, with a valid header checksum."""
    frame = bytearray(lz4.frame.compress(raw, store_size=True))
    descriptor_end = 4 + 2 + 8  # magic, FLG, BD, content size
    struct.pack_into("<Q", frame, 6, content_size)
    frame[descriptor_end] = (_xxh32(bytes(frame[4:descriptor_end])) >> 8) & 0xFF
    return bytes(frame)


def _zstd_claiming(raw: bytes, content_size: int) -> bytes:
    """A zstd frame of ``raw`` whose header claims ``content_size`` bytes (a 4-byte content size field)."""
    frame = bytearray(zstandard.ZstdCompressor().compress(raw))
    assert frame[4] & 0xC0 == 0x80, "expected a 4-byte frame content size"
    struct.pack_into("<I", frame, 5 + (0 if frame[4] & 0x20 else 1), content_size)
    return bytes(frame)


TRUTH = "bench_msgs/msg/TruthState"
READS = ("topics", "messages", "payloads", "tables", "decoded")


def valid_truth(labels=("x", "y"), state=(1.0, 2.0)) -> bytes:
    return cdr.serialize(TRUTH, cdr.lite_class(TRUTH)(labels=list(labels), state=list(state)))


def hostile_file(
    records: bytes,
    compression: str = "zstd",
    compressed: bytes | None = None,
    claim: int | None = None,
    index_claim: int | None = None,
    index_length_delta: int = 0,
) -> bytes:
    """A small MCAP file (one TruthState channel; its schema and channel records, then one chunk of ``records``)
    built by hand with the lie asked for: the chunk's ``compressed`` bytes, its claimed uncompressed size
    (``claim``), its index's (``index_claim``), its index's length; no CRCs (0: not computed), so only the lie
    is wrong."""
    if compressed is None:
        compressed = {"zstd": zstandard.ZstdCompressor().compress, "lz4": lz4.frame.compress, "": bytes}[compression](
            records
        )
    size = len(records) if claim is None else claim
    schema = _rec(0x03, struct.pack("<H", 1) + _str(TRUTH) + _str("ros2msg") + _str(b""))
    channel = _rec(0x04, struct.pack("<HH", 1, 1) + _str("/truth/state") + _str("cdr") + struct.pack("<I", 0))
    out = bytearray(MAGIC + _rec(0x01, _str("ros2") + _str("hostile")) + schema + channel)
    chunk_at = len(out)
    chunk = _rec(
        0x06,
        struct.pack("<QQQI", 10, 20, size, 0) + _str(compression) + struct.pack("<Q", len(compressed)) + compressed,
    )
    out += chunk + _rec(0x0F, struct.pack("<I", 0))
    summary_start = len(out)
    out += schema + channel
    out += _rec(
        0x08,
        struct.pack("<QQQQ", 10, 20, chunk_at, len(chunk) + index_length_delta)
        + struct.pack("<I", 10)
        + struct.pack("<HQ", 1, 0)
        + struct.pack("<Q", 0)
        + _str(compression)
        + struct.pack("<QQ", len(compressed), len(records) if index_claim is None else index_claim),
    )
    out += _rec(0x02, struct.pack("<QQI", summary_start, 0, 0)) + MAGIC
    return bytes(out)


def _messages(*payloads: bytes) -> bytes:
    return b"".join(_rec(0x05, struct.pack("<HIQQ", 1, 0, 10 + k, 10 + k) + data) for k, data in enumerate(payloads))


@dataclass
class Case:
    """A hand-made file, the reads that must refuse it (the others read it as built), the reads that may do
    either (rclpy is laxer than the bench's decoders), and how many of its messages recovery keeps."""

    data: bytes
    refused: tuple[str, ...]
    kept: int
    either: tuple[str, ...] = ()


@functools.lru_cache(maxsize=1)
def hostile_cases() -> dict[str, Case]:
    """Name -> one lie each: the shapes of the issue and a few more."""
    truth = valid_truth()
    many = _messages(*[truth] * 800)  # > 64 KiB: zstd and lz4 then write a 4-byte (or 8-byte) content size
    labels_count_at = 4 + 8 + 8 + 8  # encapsulation, stamp, frame_id "" (length, NUL, padding), step
    assert struct.unpack_from("<I", truth, labels_count_at)[0] == 2
    huge_labels = bytearray(truth)
    struct.pack_into("<I", huge_labels, labels_count_at, 2**32 - 1)
    no_nul = bytearray(truth)
    assert no_nul[labels_count_at + 4 + 1] == 0
    no_nul[labels_count_at + 4 + 1] = ord("!")  # "x\0" -> "x!"
    state_count_at = len(truth) - 16 - 4
    assert struct.unpack_from("<I", truth, state_count_at)[0] == 2
    huge_state = bytearray(truth)
    struct.pack_into("<I", huge_state, state_count_at, 2**32 - 1)
    reads = READS[1:]  # all but topics: the summary is sound, the chunk is not
    cdr_reads = ("tables", "decoded")
    one = _messages(truth)
    return {
        "intact": Case(hostile_file(many), (), 800),
        "chunk and index claim 2^40 bytes": Case(hostile_file(one, claim=2**40, index_claim=2**40), READS, 0),
        "chunk claims 2^40 bytes, its index the truth": Case(hostile_file(one, claim=2**40), reads, 0),
        "chunk and index claim 2^63 bytes (lz4)": Case(
            hostile_file(one, "lz4", claim=2**63, index_claim=2**63), READS, 0
        ),
        "chunk claims 1 GiB, holds 99 bytes": Case(
            hostile_file(one, claim=MAX_CHUNK_BYTES, index_claim=MAX_CHUNK_BYTES), reads, 0
        ),
        "zstd frame claims 2 GiB": Case(hostile_file(many, compressed=_zstd_claiming(many, 2**31 - 1)), reads, 0),
        "zstd frame and chunk claim 900 MiB": Case(
            hostile_file(many, compressed=_zstd_claiming(many, 900 << 20), claim=900 << 20, index_claim=900 << 20),
            reads,
            0,
        ),
        "lz4 frame claims 2^40 bytes": Case(hostile_file(many, "lz4", compressed=_lz4_claiming(many, 2**40)), reads, 0),
        "lz4 frame and chunk claim 900 MiB": Case(
            hostile_file(
                many, "lz4", compressed=_lz4_claiming(many, 900 << 20), claim=900 << 20, index_claim=900 << 20
            ),
            reads,
            0,
        ),
        "zstd bomb: 64 MiB of zeros claimed as 1 KiB": Case(
            hostile_file(bytes(1024), compressed=zstandard.ZstdCompressor().compress(bytes(64 << 20))), reads, 0
        ),
        "chunk record past the end of the file": Case(hostile_file(one, index_length_delta=2**40), READS, 1),
        "message record past the end of its chunk": Case(
            hostile_file(b"\x05" + struct.pack("<Q", 2**40) + one[9:], ""), reads, 0
        ),
        "message record shorter than its header": Case(hostile_file(_rec(0x05, b"\x01\x00"), ""), reads, 0),
        "CDR sequence length 2^32-1 (strings)": Case(hostile_file(_messages(bytes(huge_labels))), cdr_reads, 1),
        "CDR sequence length 2^32-1 (numbers)": Case(hostile_file(_messages(bytes(huge_state))), cdr_reads, 1),
        "string without its terminator": Case(
            hostile_file(_messages(bytes(no_nul))), ("tables",), 1, either=("decoded",)
        ),
        "message of 3 bytes": Case(hostile_file(_messages(b"\x00\x01\x00")), cdr_reads, 1),
    }


def hostile_bag(directory: Path, data: bytes, template: Path) -> Path:
    """A bag directory holding ``data`` (and a metadata.yaml naming it)."""
    bag = directory / "bag"
    bag.mkdir(parents=True)
    (bag / "bag_0.mcap").write_bytes(data)
    (bag / "metadata.yaml").write_text(
        (template / "metadata.yaml").read_text().replace(next(template.glob("*.mcap")).name, "bag_0.mcap")
    )
    return bag


def _dirname(name: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in name)


@pytest.fixture(scope="session")
def hostile() -> dict[str, Case]:
    return hostile_cases()


def test_hostile_files_are_refused_or_read_as_built(bags, hostile, tmp_path):
    """Each hand-made lie: each read either refuses the file with the reader's own error or reads it as built
    (within the time and address-space bounds); recovery keeps the messages before the lie."""
    for name, case in hostile.items():
        bag = hostile_bag(tmp_path / _dirname(name), case.data, bags["leo"].directory)
        for call_name, result in read_hostile(bag, f"{name}").items():
            if isinstance(result, BagError):
                own_error(result, bag)
                assert call_name in case.refused + case.either, f"{name}: {call_name}: {result}"
            else:
                assert call_name not in case.refused, f"{name}: {call_name} read it"
        crashed = bag.with_name("crashed")
        shutil.copytree(bag, crashed)
        (crashed / "metadata.yaml").unlink()
        with bounded(f"{name}: recover"):
            done = recover(crashed)
        assert sum(done.kept.values()) == case.kept, done.summary()


def read_hostile(bag: Path, what: str) -> dict[str, Any]:
    """Each read of a hand-made bag, bounded: its result or the reader's error."""
    reader = BagReader(bag, recover=False)
    calls = {
        "topics": reader.topics,
        "messages": lambda: list(reader.messages()),
        "payloads": lambda: reader.payloads(["/truth/state"]),
        "tables": lambda: reader.tables(["/truth/state"]),
        "decoded": lambda: list(reader.decoded()),
    }
    out = {}
    for call_name, call in calls.items():
        with bounded(f"{what}: {call_name}"):
            try:
                out[call_name] = call()
            except BagError as err:
                out[call_name] = err
    return out


def test_huge_claims_are_refused_before_allocating(bags, hostile, tmp_path, traced):
    """The files that claim huge sizes (a chunk, its index, a zstd or lz4 frame header) or hide a bomb: the reads
    and recovery's scan allocate at most MEMORY_LIMIT (tracemalloc): a 2^40-byte claim is refused before any
    allocation, a 900 MiB one reads no more than the data there."""
    for name, case in hostile.items():
        if "claim" not in name:
            continue
        bag = hostile_bag(tmp_path / _dirname(name), case.data, bags["leo"].directory)
        assert all(isinstance(r, BagError) for c, r in read_hostile(bag, name).items() if c in case.refused), name
        with bounded(f"{name}: scan"):
            list(scan_messages(RecordScan(bag / "bag_0.mcap")))


HOSTILE_READ = r"""
import json, resource, sys
from pathlib import Path
from bench_engine.bag_reader import BagReader
from bench_engine.mcap_records import RecordScan
from bench_engine.bag_errors import BagError
from rclpy.serialization import deserialize_message  # noqa: F401 - loaded before the cap, as the readers use it

vm = int(next(line for line in open("/proc/self/status") if line.startswith("VmSize")).split()[1]) * 1024
cap = vm + int(sys.argv[2])
resource.setrlimit(resource.RLIMIT_AS, (cap, cap))
out = {}
for directory in sorted(Path(sys.argv[1]).iterdir()):
    bag = directory / "bag"
    reader = BagReader(bag, recover=False)
    calls = [reader.topics, lambda: list(reader.messages()), lambda: reader.payloads(["/truth/state"]),
             lambda: reader.tables(["/truth/state"]), lambda: list(reader.decoded()),
             lambda: list(RecordScan(bag / "bag_0.mcap"))]
    results = []
    for call in calls:
        try:
            call()
            results.append("ok")
        except BagError as err:
            results.append(type(err).__name__)
        except BaseException as err:
            results.append(f"ESCAPED {type(err).__name__}: {err}")
    out[directory.name] = results
print(json.dumps(out))
"""


def test_hostile_files_under_an_address_space_cap(bags, hostile, tmp_path):
    """The same files read in a subprocess whose address space is capped at 768 MiB above what it has mapped
    after its imports (every BagReader read, and recovery's scan): an allocation of what a file claims (by zstd,
    lz4 or the reader) fails there, and the MemoryError would escape the reader."""
    cases = hostile
    for name, case in cases.items():
        hostile_bag(tmp_path / _dirname(name), case.data, bags["leo"].directory)
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    res = subprocess.run(
        [sys.executable, "-c", HOSTILE_READ, str(tmp_path), str(768 << 20)],
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
    )
    assert res.returncode == 0, res.stderr[-3000:]
    results = json.loads(res.stdout.strip().splitlines()[-1])
    assert results.keys() == {_dirname(name) for name in cases}
    escaped = {name: r for name, r in results.items() if any(x.startswith("ESCAPED") for x in r)}
    assert not escaped, escaped
    for name, case in cases.items():
        assert [r == "ok" for r in results[_dirname(name)][:5]] == [
            call not in case.refused for call in READS
        ] or case.either, (name, results[_dirname(name)])


# --- the user's view: scripts/score.py on damaged bags ------------------------------------------------------------


def damaged_copies(bag: Bag, n: int, seed: int = 18) -> list[tuple[str, bytes]]:
    """``n`` damaged copies of a bag's file: truncated, bytes flipped, an 8-byte length inflated, a block zeroed
    (in turn)."""
    rng = random.Random(seed)
    data, out = bag.layout.data, []
    for i in range(n):
        kind = ("truncated", "flipped", "inflated", "zeroed")[i % 4]
        b = bytearray(data)
        if kind == "truncated":
            b = b[: rng.randrange(8, len(b))]
        elif kind == "flipped":
            for _ in range(rng.randint(1, 8)):
                p = rng.randrange(len(b))
                b[p] ^= 1 << rng.randrange(8)
        elif kind == "inflated":
            offset = rng.choice(bag.layout.records)[0] + 1
            value = struct.unpack_from("<Q", b, offset)[0]
            struct.pack_into("<Q", b, offset, (value + rng.choice([1, 1000, 2**20, 2**40, 2**63])) % 2**64)
        else:
            p = rng.randrange(len(b))
            n_zero = rng.randint(16, 4096)
            b[p : p + n_zero] = bytes(len(b[p : p + n_zero]))
        out.append((f"{kind}_{i}", bytes(b)))
    return out


def test_score_says_one_line_for_a_damaged_bag(recorded, bags, tmp_path):
    """scripts/score.py on damaged copies of a leo_radar bag: each scores (the damage missed what it reads) or
    ends with one line on stderr and a non-zero exit, never a traceback (BENCH_FUZZ_SCORE copies, two at a time;
    CI: 4, one of each kind of damage)."""
    jobs = []
    for name, data in damaged_copies(bags["leo"], SCORE_COPIES):
        directory = tmp_path / name
        shutil.copytree(recorded["leo"], directory)
        (directory / bags["leo"].mcap_name).write_bytes(data)
        jobs.append((name, directory))
    bad = []
    with ThreadPoolExecutor(2) as pool:
        for (name, _), res in zip(jobs, pool.map(lambda job: script("score.py", str(job[1])), jobs)):
            lines = res.stderr.strip().splitlines()
            if "Traceback" in res.stderr or (res.returncode != 0 and len(lines) != 1):
                bad.append((name, res.returncode, res.stderr[-1500:]))
    assert not bad, bad
