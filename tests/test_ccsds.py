"""bench_ccsds without ROS or Java: KVN numbers and epochs, the nominal epoch, OEM and TDM written and read back,
what an export maps and what it leaves out (bags written from items), the importer's mapping, reference
interpolation and its refusals. Orekit's reading of the same messages: tests/test_ccsds_orekit.py; the graph
round trip: tests/test_ccsds_roundtrip.py; hostile files: tests/test_fuzz_ccsds.py."""

from __future__ import annotations

import datetime as dt_
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench_ccsds.epochs import NOMINAL_FROM, RunTime, nominal_epoch, run_time
from bench_ccsds.export import export_bag
from bench_ccsds.ingest import _state_at, import_tdm, write_bag
from bench_ccsds.kvn import CcsdsError, epoch_text, number, parse_epoch, parse_number, utc_ns
from bench_ccsds.oem import Segment, read_oem, write_oem
from bench_ccsds.tdm import TdmSegment, read_tdm, write_tdm
from bench_engine.config import ScenarioError, load_scenario, select_variant
from bench_engine.stage import Estimate, Measurement, TruthSample
from bench_eval.scoring import load_bag
from orbit_sim.cowell import propagate
from orbit_sim.frames import GMST_RATE, gmst82
from orbit_sim.kepler import kepler_to_cartesian

ORBIT = ["x", "y", "z", "vx", "vy", "vz"]
T0 = utc_ns(dt_.datetime(2019, 12, 9, 16, 38, 29, 363424, tzinfo=dt_.UTC))


@settings(max_examples=300, derandomize=True, deadline=None)
@given(st.floats(allow_nan=False, allow_infinity=False))
def test_a_written_number_reads_back_as_the_same_double(value):
    assert parse_number(number(value), "x") == value


@settings(max_examples=300, derandomize=True, deadline=None)
@given(
    st.integers(utc_ns(dt_.datetime(1972, 1, 1, tzinfo=dt_.UTC)), utc_ns(dt_.datetime(2199, 12, 31, tzinfo=dt_.UTC)))
)
def test_an_epoch_reads_back_to_the_nanosecond_in_either_calendar_form(ns):
    text = epoch_text(ns)
    assert parse_epoch(text, "x") == ns == parse_epoch(text + "Z", "x")
    day = dt_.date.fromisoformat(text[:10])
    assert parse_epoch(f"{day.year}-{day.timetuple().tm_yday:03d}{text[10:]}", "x") == ns


@pytest.mark.parametrize(
    "text, problem",
    [
        ("2016-12-31T23:59:60", "leap second"),
        ("1960-01-01T00:00:00", "outside"),
        ("2019-02-30T00:00:00", "no calendar"),
        ("2019-366T00:00:00", "no calendar"),
        ("2019-01-01 00:00:00", "not a CCSDS epoch"),
        ("2019-01-01T24:00:00", "time of day"),
        ("nan", "not a CCSDS epoch"),
    ],
)
def test_bad_epochs_are_one_line_errors(text, problem):
    with pytest.raises(CcsdsError, match=problem):
        parse_epoch(text, "f.tdm: line 3")


@pytest.mark.parametrize("text", ["nan", "inf", "-Infinity", "1_000", "0x10", "1e400", "", "1.0.0", "--1"])
def test_what_is_not_a_ccsds_number_is_refused(text):
    with pytest.raises(CcsdsError):
        parse_number(text, "f")


@pytest.mark.parametrize("theta0", [0.0, np.radians(40.0), 3.0, 2 * np.pi - 1e-9])
def test_the_nominal_epoch_is_the_first_instant_whose_gmst_is_theta0(theta0):
    ns = nominal_epoch(theta0)
    start = utc_ns(NOMINAL_FROM)
    assert start <= ns < start + 86164.1e9  # within one sidereal day
    days, rest = divmod(ns, 86_400_000_000_000)
    gap = np.angle(np.exp(1j * (gmst82(2440587.5 + days, rest / 86_400_000_000_000) - theta0)))
    assert abs(gap) < 1e-12
    assert abs(gap) < GMST_RATE * 1e-9  # the nanosecond is the limit


def test_run_time_follows_the_scenario():
    iss = select_variant(load_scenario("leo_radar"), "iss")
    assert run_time(iss) == RunTime(T0, False)
    paper = run_time(load_scenario("leo_radar"))
    assert paper.nominal and paper.epoch_ns == nominal_epoch(np.radians(40.0))
    assert paper.sim(paper.utc(123)) == 123


def _orbit(times: np.ndarray) -> np.ndarray:
    x0 = kepler_to_cartesian(6.9e6, 0.001, 0.9, 0.3, 0.2, 0.1)
    return propagate(x0, np.asarray(times, dtype=float))


def test_oem_written_and_read_back(tmp_path):
    t = np.arange(0.0, 50.0, 10.0)
    states = _orbit(t)
    cov = np.diag([4e4, 4e4, 4e4, 1.0, 1.0, 1.0]) + 3.0
    accel = np.hstack((states, np.full((len(t), 3), 8.1)))
    segments = [
        Segment(
            "SAT A",
            "2019-001A",
            "TEME",
            [T0 + int(s * 1e9) for s in t],
            states,
            covariances=[(T0, cov), (T0 + 40_000_000_000, 2 * cov)],
            comments=["first"],
        ),
        Segment("SAT A", "2019-001A", "TEME", [T0 + int(s * 1e9) + 10**11 for s in t], accel),
    ]
    path = write_oem(tmp_path / "a.oem", segments, "TEST", T0, ["header comment"])
    back = read_oem(path)
    assert [s.object_name for s in back] == ["SAT A", "SAT A"] and back[0].frame == "TEME"
    np.testing.assert_allclose(back[0].states, states, rtol=3e-16, atol=0)
    np.testing.assert_allclose(back[1].states, accel, rtol=3e-16, atol=0)
    assert back[0].epochs == segments[0].epochs and back[1].covariances == []
    assert [e for e, _ in back[0].covariances] == [T0, T0 + 40_000_000_000]
    np.testing.assert_allclose(back[0].covariances[1][1], 2 * cov, rtol=3e-16)


def test_tdm_written_and_read_back(tmp_path):
    obs = {
        "RANGE": [(T0, 1.5e6), (T0 + 10**8, 1.49e6)],
        "ANGLE_1": [(T0, 6.2), (T0 + 10**8, 0.01)],
        "ANGLE_2": [(T0, 0.2), (T0 + 10**8, 0.21)],
        "DOPPLER_INSTANTANEOUS": [(T0, -3.2e3)],
    }
    seg = TdmSegment(
        {
            "TIME_SYSTEM": "UTC",
            "PARTICIPANT_1": "radar",
            "PARTICIPANT_2": "sat",
            "MODE": "SEQUENTIAL",
            "PATH": "1,2,1",
            "ANGLE_TYPE": "AZEL",
            "RANGE_UNITS": "km",
        },
        obs,
    )
    back = read_tdm(write_tdm(tmp_path / "a.tdm", [seg], "TEST", T0))[0]
    assert back.metadata == seg.metadata
    for key, values in obs.items():
        assert [e for e, _ in back.observations[key]] == [e for e, _ in values]
        np.testing.assert_allclose([v for _, v in back.observations[key]], [v for _, v in values], rtol=5e-16)
    text = (tmp_path / "a.tdm").read_text()
    assert f"ANGLE_1 = 2019-12-09T16:38:29.363424000 {np.degrees(6.2):.16e}" in text  # 6.2 rad in degrees


def _run(cfg: dict) -> dict:
    return {"scenario": cfg, "estimators": ["f"], "seed": 1}


def _radar_scenario() -> dict:
    cfg = select_variant(load_scenario("leo_radar"), "iss")
    return {
        k: cfg[k]
        for k in (
            "scenario",
            "earth",
            "time",
            "truth",
            "sensors",
            "filter_defaults",
            "filters",
            "estimators",
            "scoring",
        )
    }


def test_export_maps_what_ccsds_holds_and_lists_the_rest(tmp_path):
    """Synthetic bags: a two-satellite eci state (one OEM segment each), an LVLH state (no OEM frame), an
    inter-satellite RangeAzEl (RANGE only, angles listed), a range-rate VectorMeasurement (DOPPLER_INSTANTANEOUS)
    and GNSS positions (no TDM keyword)."""
    cfg = {"scenario": "synthetic", "time": {"start": 0.0, "dt": 1.0, "duration": 3.0}, "earth": {"theta0_deg": 10.0}}
    t_ns = [0, 1_000_000_000, 2_000_000_000]
    pair = np.hstack((_orbit([0, 1, 2]), _orbit([0, 1, 2]) * 1.001))
    labels2 = [c + s for s in ("1", "2") for c in ORBIT]
    R3 = np.diag([1.0, 1e-6, 1e-6])
    streams = [
        (
            "/truth/state",
            "bench_msgs/msg/TruthState",
            [TruthSample(k, t, "eci", labels2, pair[k]) for k, t in enumerate(t_ns)],
        ),
        (
            "/pairf/estimate",
            "bench_msgs/msg/StateEstimate",
            [Estimate(k, t, "eci", "pairf", labels2, pair[k], np.eye(12) * (k + 1)) for k, t in enumerate(t_ns)],
        ),
        (
            "/rel/estimate",
            "bench_msgs/msg/StateEstimate",
            [Estimate(k, t, "lvlh", "rel", ORBIT, np.ones(6), np.eye(6)) for k, t in enumerate(t_ns)],
        ),
        (
            "/isl/measurement",
            "bench_msgs/msg/RangeAzEl",
            [
                Measurement(k, t, "lvlh", "isl", np.array([100.0 + k, 0.1, 0.2]), R3, ["range", "azimuth", "elevation"])
                for k, t in enumerate(t_ns)
            ],
        ),
        (
            "/kbr/measurement",
            "bench_msgs/msg/VectorMeasurement",
            [
                Measurement(k, t, "eci", "kbr", np.array([1e-3 * k]), np.eye(1), ["range_rate"])
                for k, t in enumerate(t_ns)
            ],
        ),
        (
            "/gnss/measurement",
            "bench_msgs/msg/VectorMeasurement",
            [Measurement(k, t, "eci", "gnss", np.ones(3), np.eye(3), ["x", "y", "z"]) for k, t in enumerate(t_ns)],
        ),
    ]
    write_bag(tmp_path / "bag", {"scenario": cfg, "estimators": ["pairf", "rel"], "seed": 0}, streams)
    result = export_bag(tmp_path / "bag", tmp_path / "out")
    assert sorted(p.name for p in result.written) == ["isl.tdm", "kbr.tdm", "pairf.oem", "truth.oem"]
    assert set(result.skipped) == {"rel", "gnss", "isl (part)"}
    assert "lvlh" in result.skipped["rel"] and "no keyword" in result.skipped["gnss"]
    assert "azimuth and elevation" in result.skipped["isl (part)"]
    oem = read_oem(tmp_path / "out" / "pairf.oem")
    assert len(oem) == 2
    np.testing.assert_allclose(oem[1].states, pair[:, 6:], rtol=3e-16)
    np.testing.assert_allclose(oem[1].covariances[2][1], 3 * np.eye(6), rtol=3e-16)
    isl = read_tdm(tmp_path / "out" / "isl.tdm")[0]
    assert set(isl.observations) == {"RANGE"} and "ANGLE_TYPE" not in isl.metadata
    kbr = read_tdm(tmp_path / "out" / "kbr.tdm")[0]
    assert [v for _e, v in kbr.observations["DOPPLER_INSTANTANEOUS"]] == pytest.approx([0.0, 1e-3, 2e-3], rel=1e-15)
    clock = run_time(cfg)
    assert [e for e, _ in kbr.observations["DOPPLER_INSTANTANEOUS"]] == [clock.utc(t) for t in t_ns]
    with pytest.raises(ScenarioError, match="no estimates of"):
        export_bag(tmp_path / "bag", tmp_path / "out2", estimators=["nope"])


def _radar_tdm(path: Path, epochs: list[int], metadata: dict | None = None, keys=("RANGE", "ANGLE_1", "ANGLE_2")):
    meta = {
        "TIME_SYSTEM": "UTC",
        "PARTICIPANT_1": "radar",
        "PARTICIPANT_2": "sat",
        "MODE": "SEQUENTIAL",
        "PATH": "1,2,1",
        "ANGLE_TYPE": "AZEL",
        **(metadata or {}),
    }
    values = {"RANGE": 1.6e6, "ANGLE_1": 4.0, "ANGLE_2": 0.15}
    seg = TdmSegment(meta, {k: [(e, values[k]) for e in epochs] for k in keys})
    return write_tdm(path, [seg], "TEST", T0)


def test_import_maps_epochs_to_measurements_on_the_grid(tmp_path):
    cfg = _radar_scenario()
    start = T0 + int(cfg["time"]["start"] * 1e9)
    epochs = [start + k * 100_000_000 for k in (0, 1, 5)]
    tdm = _radar_tdm(tmp_path / "a.tdm", epochs)
    seg = read_tdm(tdm)[0]
    seg.observations["ANGLE_2"] = seg.observations["ANGLE_2"][:2]  # the last epoch lacks its elevation
    seg.other["RECEIVE_FREQ"] = [(epochs[0], 1.0)]
    write_tdm(tdm, [seg], "TEST", T0)
    imported = import_tdm(tdm, cfg, tmp_path / "bag")
    assert imported.measurements == {"radar": 2} and imported.reference == 0
    assert any("lack one of" in n for n in imported.notes) and any("RECEIVE_FREQ" in n for n in imported.notes)
    data = load_bag(tmp_path / "bag")
    assert sorted(data.measurements["radar"]) == [0, 1]
    np.testing.assert_allclose(data.measurements["radar"][1], [1.6e6, 4.0, 0.15], rtol=1e-15)


@pytest.mark.parametrize(
    "change, problem",
    [
        ({"TIME_SYSTEM": "TAI"}, "reads UTC"),
        ({"ANGLE_TYPE": "RADEC"}, "AZEL"),
        ({"PARTICIPANT_1": "TIRA"}, None),  # the only ground radar takes it, with a note
    ],
)
def test_import_refuses_what_the_scenario_cannot_take(tmp_path, change, problem):
    cfg = _radar_scenario()
    start = T0 + int(cfg["time"]["start"] * 1e9)
    tdm = _radar_tdm(tmp_path / "a.tdm", [start, start + 100_000_000], change)
    if problem is None:
        assert any("taken as sensor 'radar'" in n for n in import_tdm(tdm, cfg, tmp_path / "bag").notes)
        return
    with pytest.raises(CcsdsError, match=problem) as err:
        import_tdm(tdm, cfg, tmp_path / "bag")
    assert str(err.value).startswith(str(tdm)) and "\n" not in str(err.value)


def test_import_refuses_epochs_off_the_scenarios_time_line(tmp_path):
    cfg = _radar_scenario()
    start = T0 + int(cfg["time"]["start"] * 1e9)
    for epochs, problem in (
        ([start - 10**9], "before the scenario's time.start"),
        ([start, start + 10_000_000], "two epochs in step 0"),
        ([T0 - 10**12], "before the run's epoch"),
    ):
        with pytest.raises(CcsdsError, match=problem):
            import_tdm(_radar_tdm(tmp_path / "a.tdm", epochs), cfg, tmp_path / f"bag{len(epochs)}{epochs[0]}")


def test_the_reference_is_interpolated_between_its_lines(tmp_path):
    """Cubic Hermite on positions and velocities: at the midpoints of a 10 s LEO ephemeris within 1 mm and
    1 µm/s of the orbit (its error is ~h^4 |r''''| / 384 = 0.3 mm), exact at the lines, None outside."""
    t = np.arange(0.0, 121.0, 10.0)
    states = _orbit(t)
    epochs = [T0 + int(s * 1e9) for s in t]
    mid = _orbit(np.concatenate(([0.0], t[:-1] + 5.0)))[1:]
    got = np.array([_state_at(epochs, states, e + 5_000_000_000) for e in epochs[:-1]])
    assert np.abs(got[:, :3] - mid[:, :3]).max() < 1e-3 and np.abs(got[:, 3:] - mid[:, 3:]).max() < 1e-6
    assert np.array_equal(_state_at(epochs, states, epochs[3]), states[3])
    assert _state_at(epochs, states, epochs[0] - 1) is None and _state_at(epochs, states, epochs[-1] + 1) is None


def test_a_reference_in_another_frame_is_refused(tmp_path):
    cfg = _radar_scenario()
    start = T0 + int(cfg["time"]["start"] * 1e9)
    tdm = _radar_tdm(tmp_path / "a.tdm", [start])
    oem = write_oem(tmp_path / "r.oem", [Segment("S", "S", "EME2000", [start], _orbit([0.0]))], "TEST", T0)
    with pytest.raises(CcsdsError, match="must be TEME, EARTH, UTC"):
        import_tdm(tdm, cfg, tmp_path / "bag", reference=oem)
