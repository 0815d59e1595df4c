"""Hostile and malformed CCSDS files through the bench's readers (bench_ccsds.oem.read_oem, tdm.read_tdm) and the
TDM importer: damaged copies of messages the bench writes (a character replaced, a line dropped, repeated, moved
or inserted from a list of hostile lines, the file cut anywhere) and hand-made files for what mutation rarely
hits (binary, XML, empty, huge, a single endless line).

Property of every example: the reader returns segments, or raises its own error (kvn.CcsdsError: one line that
starts with the file's path); the importer returns, or raises that or a ScenarioError, also one line; never
another exception. The commands (scripts/import_tdm.py, scripts/export.py) print one line and exit 2.

Budget as tests/test_fuzz_readers.py: ``BENCH_FUZZ_EXAMPLES`` examples per reader (default 40, derandomised: the
same every run); set it for a larger campaign with fresh random examples::

    BENCH_FUZZ_EXAMPLES=2000 .venv/bin/python -m pytest tests/test_fuzz_ccsds.py
"""

from __future__ import annotations

import datetime as dt_
import os
from pathlib import Path

import numpy as np
import pytest
from graph_helpers import script
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import bench_ccsds.kvn as kvn
from bench_ccsds.ingest import import_tdm
from bench_ccsds.kvn import CcsdsError, utc_ns
from bench_ccsds.oem import Segment, read_oem, write_oem
from bench_ccsds.tdm import TdmSegment, read_tdm, write_tdm
from bench_engine.config import ScenarioError, load_scenario, select_variant

EXAMPLES = int(os.environ.get("BENCH_FUZZ_EXAMPLES", "40"))
CAMPAIGN = "BENCH_FUZZ_EXAMPLES" in os.environ
FUZZ = settings(
    max_examples=EXAMPLES,
    derandomize=not CAMPAIGN,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
T0 = utc_ns(dt_.datetime(2019, 12, 9, 16, 38, 29, 363424, tzinfo=dt_.UTC))
START = T0 + 5_724_900_000_000
HOSTILE_LINES = [
    "META_START",
    "META_STOP",
    "DATA_START",
    "DATA_STOP",
    "COVARIANCE_START",
    "COVARIANCE_STOP",
    "RANGE = 2019-12-09T18:13:54.263424 nan",
    "ANGLE_1 = 2019-12-09T18:13:54.263424 1e999",
    "EPOCH = 2016-12-31T23:59:60",
    "REF_FRAME = EME2000",
    "TIME_SYSTEM = TAI",
    "ANGLE_TYPE = RADEC",
    "2019-12-09T18:13:54.263424 1 2 3",
    "1.0",
    "= =",
    "lower case = x",
    "X" * 5000,
    "RANGE_UNITS = RU",
    "CCSDS_OEM_VERS = 9.9",
    "2019-343T18:13:54 1 2 3 4 5 6",
]


def _messages(directory: Path) -> tuple[Path, Path]:
    """A small TDM (radar over the leo_radar iss variant's grid) and OEM (covariances, two segments)."""
    epochs = [START + k * 100_000_000 for k in range(4)]
    tdm = write_tdm(
        directory / "m.tdm",
        [
            TdmSegment(
                {
                    "TIME_SYSTEM": "UTC",
                    "PARTICIPANT_1": "radar",
                    "PARTICIPANT_2": "ISS",
                    "MODE": "SEQUENTIAL",
                    "PATH": "1,2,1",
                    "ANGLE_TYPE": "AZEL",
                    "RANGE_UNITS": "km",
                },
                {
                    "RANGE": [(e, 1.6e6 + k) for k, e in enumerate(epochs)],
                    "ANGLE_1": [(e, 4.0) for e in epochs],
                    "ANGLE_2": [(e, 0.15) for e in epochs],
                },
            )
        ],
        "T",
        T0,
    )
    state = np.array([[4.3e6, -1.9e6, 4.9e6, 2.5e3, 7.2e3, -0.5e3]])
    oem = write_oem(
        directory / "m.oem",
        [
            Segment(
                "ISS",
                "1998-067A",
                "TEME",
                epochs[:2],
                np.vstack([state, state + 1.0]),
                covariances=[(epochs[0], np.eye(6) * 4.0)],
            ),
            Segment("ISS", "1998-067A", "TEME", epochs[2:], np.vstack([state, state + 2.0])),
        ],
        "T",
        T0,
    )
    return tdm, oem


@pytest.fixture(scope="module")
def messages(tmp_path_factory):
    return _messages(tmp_path_factory.mktemp("ccsds-fuzz"))


@st.composite
def damaged(draw, text: str) -> str:
    lines = text.split("\n")
    kind = draw(st.sampled_from(["char", "drop", "repeat", "move", "insert", "cut"]))
    i = draw(st.integers(0, len(lines) - 1))
    if kind == "char":
        line = lines[i]
        j = draw(st.integers(0, max(len(line) - 1, 0)))
        lines[i] = line[:j] + draw(st.characters(max_codepoint=0x3000)) + line[j + 1 :]
    elif kind == "drop":
        del lines[i]
    elif kind == "repeat":
        lines.insert(i, lines[i])
    elif kind == "move":
        lines.insert(draw(st.integers(0, len(lines) - 1)), lines.pop(i))
    elif kind == "insert":
        lines.insert(i, draw(st.sampled_from(HOSTILE_LINES)))
    else:
        return text[: draw(st.integers(0, len(text)))]
    return "\n".join(lines)


def _check_one_line(err: Exception, path: Path) -> None:
    text = str(err)
    assert "\n" not in text and text.startswith(str(path)), text


def _fuzz(reader, source: Path, data: st.DataObject, tmp_path: Path) -> None:
    path = tmp_path / f"fuzzed{source.suffix}"
    path.write_text(data.draw(damaged(source.read_text())), encoding="utf-8", errors="surrogateescape")
    try:
        segments = reader(path)
    except CcsdsError as err:
        _check_one_line(err, path)
        return
    assert segments


@FUZZ
@given(data=st.data())
def test_fuzzed_tdms_are_read_or_refused_in_one_line(messages, data, tmp_path):
    _fuzz(read_tdm, messages[0], data, tmp_path)


@FUZZ
@given(data=st.data())
def test_fuzzed_oems_are_read_or_refused_in_one_line(messages, data, tmp_path):
    _fuzz(read_oem, messages[1], data, tmp_path)


@settings(
    max_examples=max(EXAMPLES // 4, 5),
    derandomize=not CAMPAIGN,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(data=st.data())
def test_fuzzed_imports_finish_or_fail_in_one_line(messages, data, tmp_path_factory):
    cfg = select_variant(load_scenario("leo_radar"), "iss")
    work = tmp_path_factory.mktemp("import")
    tdm, oem = work / "fuzzed.tdm", work / "fuzzed.oem"
    tdm.write_text(data.draw(damaged(messages[0].read_text())), encoding="utf-8", errors="surrogateescape")
    oem.write_text(data.draw(damaged(messages[1].read_text())), encoding="utf-8", errors="surrogateescape")
    try:
        import_tdm(tdm, cfg, work / "bag", reference=oem)
    except (CcsdsError, ScenarioError) as err:
        assert "\n" not in str(err) and (str(err).startswith(str(work)) or "already exists" in str(err)), str(err)


def test_hand_made_hostile_files(tmp_path, monkeypatch):
    cases = {
        "binary.tdm": (b"\x89PNG\r\n\x1a\n" + bytes(range(256)), "not ASCII"),
        "xml.oem": (b'<?xml version="1.0"?>\n<oem id="CCSDS_OEM_VERS" version="2.0"/>\n', "XML message"),
        "empty.tdm": (b"", "ends where"),
        "line.tdm": (b"CCSDS_TDM_VERS = 2.0\n" + b"A" * 10_000, "characters"),
        "nul.tdm": (b"CCSDS_TDM_VERS = 2.0\x00\n", "control characters"),
        "big.tdm": (b"CCSDS_TDM_VERS = 2.0\n" + b"COMMENT x\n" * 3000, "larger than"),
    }
    monkeypatch.setattr(kvn, "MAX_BYTES", 20_000)
    for name, (content, problem) in cases.items():
        path = tmp_path / name
        path.write_bytes(content)
        reader = read_oem if name.endswith(".oem") else read_tdm
        with pytest.raises(CcsdsError, match=problem) as err:
            reader(path)
        _check_one_line(err.value, path)
    with pytest.raises(CcsdsError, match="cannot be read"):
        read_tdm(tmp_path / "missing.tdm")
    with pytest.raises(CcsdsError, match="a TDM starts with"):
        read_tdm(write_oem(tmp_path / "an.oem", [Segment("S", "S", "TEME", [T0], np.ones((1, 6)))], "T", T0))


def test_the_commands_say_what_is_wrong_in_one_line(messages, tmp_path):
    broken = tmp_path / "broken.tdm"
    broken.write_text(
        messages[0]
        .read_text()
        .replace("ANGLE_2 = 2019-12-09T18:13:54.463424000", "ANGLE_2 = 2019-12-09T18:13:54.4634x")
    )
    result = script(
        "import_tdm.py",
        str(broken),
        "--scenario",
        "leo_radar",
        "--variant",
        "iss",
        "--out",
        str(tmp_path / "run"),
        timeout=120,
    )
    assert result.returncode == 2, result.stderr
    assert result.stderr.strip().count("\n") == 0 and "Traceback" not in result.stderr
    assert f"{broken}: line" in result.stderr and "not a CCSDS epoch" in result.stderr
    result = script("export.py", str(tmp_path), "--out", str(tmp_path / "x"), timeout=120)
    assert result.returncode == 2 and "not a bag recorded by this bench" in result.stderr
    assert result.stderr.strip().count("\n") == 0
