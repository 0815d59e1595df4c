"""A TDM (and optionally an OEM as the reference trajectory) turned into a bag the bench replays like its own.

The scenario says what the data are: its ground radar sensor (station, noise R, range rate or not), its time
line (``time.epoch``, else the nominal epoch: bench_ccsds.epochs) and grid (``time.start``, ``time.dt``). Each
TDM segment goes to one ground radar sensor of the scenario: the one ``sensor`` names, else the one named like
its PARTICIPANT_1, else the scenario's only ground radar. An epoch with RANGE, ANGLE_1 and ANGLE_2 (ANGLE_TYPE
AZEL; and DOPPLER_INSTANTANEOUS when the sensor measures range rate) is one measurement: z = (range, azimuth,
elevation[, range rate]) in SI, the sensor's R, stamped with its sim time (UTC epoch - the run's epoch) and
numbered by its step on the scenario's grid, round((t - time.start) / time.dt). Epochs missing a component are
counted and skipped; other keywords are counted and ignored (the summary says which). Two epochs of one sensor
in one step, an epoch before time.start or before the run's epoch, a TIME_SYSTEM other than UTC, and any
malformed file stop the import with one line naming the file and the problem.

The reference OEM (REF_FRAME TEME, CENTER_NAME EARTH, TIME_SYSTEM UTC) becomes the run's truth at every
measurement step its span covers: the state of a data line at that epoch when there is one, else the cubic
Hermite interpolant of positions and velocities between the two lines around it. Steps outside its span have no
reference.

The bag written: the measurement topics (and ``/truth/state``) as CDR in a rosbag2 MCAP bag with
``run_config.yaml``; its ``time.duration`` is lengthened when the data run past the scenario's grid.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench_ccsds.epochs import FRAMES, TIME_SYSTEM, run_time
from bench_ccsds.kvn import CcsdsError, epoch_text
from bench_ccsds.oem import read_oem
from bench_ccsds.tdm import TdmSegment, read_tdm
from bench_engine import yamlio
from bench_engine.bag_writer import BagWriter
from bench_engine.cdr import lite_class, serialize
from bench_engine.config import ScenarioError
from bench_engine.graph import TRUTH_TOPIC, TRUTH_TYPE, measurement_topic
from bench_engine.labels import ORBIT
from bench_engine.scenario import scenario_seed
from bench_engine.sim_clock import SimClock
from bench_engine.stage import Measurement, TruthSample, codec
from bench_engine.timegrid import build_time
from radar_sensor.sensor import build_sensor
from radar_sensor.sensor_types import sensor_names

RADAR_KEYWORDS = ("RANGE", "ANGLE_1", "ANGLE_2")
RANGE_RATE = "DOPPLER_INSTANTANEOUS"


@dataclass
class Imported:
    """What an import made of its files: measurements per sensor, reference samples, what was skipped."""

    bag_dir: Path
    measurements: dict[str, int] = field(default_factory=dict)
    reference: int = 0
    notes: list[str] = field(default_factory=list)

    def summary(self) -> str:
        lines = [
            f"{self.bag_dir}: "
            + ", ".join(f"{n} measurements of sensor '{s}'" for s, n in self.measurements.items())
            + (f", the reference at {self.reference} of their steps" if self.reference else ", no reference")
        ]
        return "\n".join(lines + [f"note: {note}" for note in self.notes])


def radar_sensors(cfg: dict) -> dict:
    """The scenario's ground radar sensors, built (name -> radar_sensor Sensor)."""
    sensors = {name: build_sensor(cfg, name) for name in sensor_names(cfg)}
    return {name: s for name, s in sensors.items() if s.kind == "ground_radar"}


def import_tdm(
    tdm: str | Path, cfg: dict, bag_dir: str | Path, reference: str | Path | None = None, sensor: str | None = None
) -> Imported:
    """Write the bag of ``tdm`` (and ``reference``) under the scenario ``cfg`` into ``bag_dir``."""
    tdm, bag_dir = Path(tdm), Path(bag_dir)
    radars = radar_sensors(cfg)
    if not radars:
        raise ScenarioError("the scenario has no ground_radar sensor to give the TDM's measurements to")
    if sensor is not None and sensor not in radars:
        raise ScenarioError(
            f"--sensor {sensor!r} is not a ground_radar sensor of the scenario; it has {sorted(radars)}"
        )
    clock, grid = run_time(cfg), build_time(cfg)
    result = Imported(bag_dir)
    measured: dict[str, dict[int, Measurement]] = {}
    for n, seg in enumerate(read_tdm(tdm), start=1):
        name = _sensor_for(seg, radars, sensor, f"{tdm}: segment {n}")
        if name != seg.metadata["PARTICIPANT_1"]:
            result.notes.append(
                f"segment {n}: PARTICIPANT_1 {seg.metadata['PARTICIPANT_1']!r} taken as sensor '{name}'"
            )
        for m in _measurements(seg, radars[name], clock, f"{tdm}: segment {n}", result):
            k = int(round((m.t_ns - grid.start_ns) / grid.dt_ns))
            if m.t_ns < grid.start_ns:
                raise CcsdsError(
                    f"{tdm}: segment {n}: epoch {epoch_text(clock.utc(m.t_ns))} is before the scenario's "
                    f"time.start ({grid.start_ns * 1e-9:g} s after its epoch): lower time.start"
                )
            if k in measured.setdefault(name, {}):
                raise CcsdsError(
                    f"{tdm}: sensor '{name}' has two epochs in step {k} ({epoch_text(clock.utc(m.t_ns))} "
                    f"and {epoch_text(clock.utc(measured[name][k].t_ns))}): choose a time.dt below "
                    "their spacing"
                )
            m.step = k
            measured[name][k] = m
    if not any(measured.values()):
        raise CcsdsError(f"{tdm}: no epoch holds a whole measurement (RANGE, ANGLE_1 and ANGLE_2 at one epoch)")
    steps = sorted({k for by_step in measured.values() for k in by_step})
    truth = _reference_samples(Path(reference), clock, grid, measured, result) if reference is not None else []
    run = _run_config(cfg, grid, steps[-1], bag_dir, tdm, reference)
    _write_bag(bag_dir, run, measured, radars, truth, grid.start_ns)
    result.measurements = {name: len(by_step) for name, by_step in measured.items()}
    result.reference = len(truth)
    return result


def _sensor_for(seg: TdmSegment, radars: dict, sensor: str | None, where: str) -> str:
    if sensor is not None:
        return sensor
    if seg.metadata["PARTICIPANT_1"] in radars:
        return seg.metadata["PARTICIPANT_1"]
    if len(radars) == 1:
        return next(iter(radars))
    raise CcsdsError(
        f"{where}: PARTICIPANT_1 {seg.metadata['PARTICIPANT_1']!r} is none of the scenario's ground "
        f"radars {sorted(radars)}: name one with --sensor"
    )


def _measurements(seg: TdmSegment, radar, clock, where: str, result: Imported) -> list[Measurement]:
    if seg.metadata["TIME_SYSTEM"] != TIME_SYSTEM:
        raise CcsdsError(f"{where}: TIME_SYSTEM {seg.metadata['TIME_SYSTEM']}: the importer reads UTC")
    if ("ANGLE_1" in seg.observations or "ANGLE_2" in seg.observations) and seg.metadata.get("ANGLE_TYPE") != "AZEL":
        raise CcsdsError(
            f"{where}: ANGLE_TYPE {seg.metadata.get('ANGLE_TYPE')!r}: a ground radar's angles are "
            "AZEL (azimuth, elevation)"
        )
    wanted = RADAR_KEYWORDS + ((RANGE_RATE,) if len(radar.model.labels) == 4 else ())
    values: dict[int, dict[str, float]] = {}
    for key in wanted:
        for epoch, value in seg.observations.get(key, []):
            if key in values.setdefault(epoch, {}):
                raise CcsdsError(f"{where}: {key} given twice at {epoch_text(epoch)}")
            values[epoch][key] = value
    unused = sorted(set(seg.observations) - set(wanted)) + sorted(seg.other)
    if unused:
        result.notes.append(f"{where}: ignored keywords {', '.join(unused)} (the sensor does not measure them)")
    whole = sorted(e for e, v in values.items() if len(v) == len(wanted))
    if len(whole) < len(values):
        result.notes.append(f"{where}: {len(values) - len(whole)} epochs lack one of {', '.join(wanted)}: skipped")
    out = []
    for epoch in whole:
        t_ns = clock.sim(epoch)
        if t_ns < 0:
            raise CcsdsError(
                f"{where}: epoch {epoch_text(epoch)} is before the run's epoch {epoch_text(clock.epoch_ns)}"
            )
        z = np.array([values[epoch][k] for k in wanted])
        z[1] = np.mod(z[1], 2.0 * np.pi)
        if not -np.pi / 2 <= z[2] <= np.pi / 2 or z[0] <= 0.0:
            raise CcsdsError(
                f"{where}: at {epoch_text(epoch)} RANGE must be > 0 and ANGLE_2 (elevation) in [-90, 90] deg"
            )
        out.append(Measurement(0, t_ns, radar.frame_id, radar.name, z, radar.R.copy(), list(radar.model.labels)))
    return out


def _reference_samples(path: Path, clock, grid, measured: dict, result: Imported) -> list[TruthSample]:
    segments = read_oem(path)
    for seg in segments:
        where = f"{path}: segment of {seg.object_name!r}"
        if seg.frame != FRAMES["eci"] or seg.center.upper() != "EARTH" or seg.time_system != TIME_SYSTEM:
            raise CcsdsError(
                f"{where}: REF_FRAME {seg.frame}, CENTER_NAME {seg.center}, TIME_SYSTEM {seg.time_system}: "
                "the reference must be TEME, EARTH, UTC (the bench's eci on its UTC time line)"
            )
    if len({seg.object_name for seg in segments}) > 1:
        raise CcsdsError(
            f"{path}: the reference holds several objects {sorted({s.object_name for s in segments})}; give one"
        )
    epochs = np.array([e for seg in segments for e in seg.epochs], dtype=object)
    states = np.vstack([seg.states[:, :6] for seg in segments])
    order = np.argsort(epochs)
    epochs, states = [int(e) for e in epochs[order]], states[order]
    steps = {}
    for by_step in measured.values():
        for k, m in by_step.items():
            steps.setdefault(k, m.t_ns)
    samples = []
    for k, t_ns in sorted(steps.items()):
        state = _state_at(epochs, states, clock.utc(t_ns))
        if state is not None:
            samples.append(TruthSample(k, t_ns, "eci", list(ORBIT), state))
    if not samples:
        result.notes.append(f"{path}: the reference covers none of the measurements' epochs")
    elif len(samples) < len(steps):
        result.notes.append(f"{path}: the reference covers {len(samples)} of the {len(steps)} measurement steps")
    return samples


def _state_at(epochs: list[int], states: np.ndarray, utc: int) -> np.ndarray | None:
    """The state at ``utc``: a data line's, or the cubic Hermite interpolant between the lines around it; None
    outside the ephemeris."""
    i = int(np.searchsorted(np.array(epochs, dtype=np.int64), utc))
    if i < len(epochs) and epochs[i] == utc:
        return states[i].copy()
    if i == 0 or i == len(epochs):
        return None
    h = (epochs[i] - epochs[i - 1]) * 1e-9
    s = (utc - epochs[i - 1]) * 1e-9 / h
    r0, v0, r1, v1 = states[i - 1, :3], states[i - 1, 3:6] * h, states[i, :3], states[i, 3:6] * h
    h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
    d00, d10, d01, d11 = 6 * s**2 - 6 * s, 3 * s**2 - 4 * s + 1, -6 * s**2 + 6 * s, 3 * s**2 - 2 * s
    r = h00 * r0 + h10 * v0 + h01 * r1 + h11 * v1
    v = (d00 * r0 + d10 * v0 + d01 * r1 + d11 * v1) / h
    return np.concatenate((r, v))


def _run_config(cfg: dict, grid, last_step: int, bag_dir: Path, tdm: Path, reference) -> dict:
    cfg = copy.deepcopy(cfg)
    if last_step >= grid.steps:
        cfg["time"]["duration"] = last_step * grid.dt
    return {
        "scenario": cfg,
        "estimators": [],
        "record": True,
        "source": "ccsds",
        "out": str(bag_dir.parent),
        "bag_dir": str(bag_dir),
        "seed": scenario_seed(cfg),
        "ccsds_import": {"tdm": str(tdm.resolve()), "reference": str(Path(reference).resolve()) if reference else None},
    }


def _write_bag(bag_dir: Path, run: dict, measured: dict, radars: dict, truth: list[TruthSample], start_ns: int) -> None:
    streams = [
        (measurement_topic(name), "bench_msgs/msg/RangeAzEl", sorted(by_step.values(), key=lambda m: m.t_ns))
        for name, by_step in measured.items()
    ]
    if truth:
        streams.append((TRUTH_TOPIC, TRUTH_TYPE, truth))
    write_bag(bag_dir, run, streams, start_ns)


def write_bag(bag_dir: Path, run: dict, streams: list[tuple[str, str, list]], start_ns: int = 0) -> None:
    """A bag of items: each stream (topic, message type, items) encoded by its registered codec, written in
    sim-time order with sim-time log times (bench_engine.sim_clock.SimClock), and ``run`` as its run_config.yaml."""
    if Path(bag_dir).exists():
        raise ScenarioError(f"{bag_dir} already exists: choose another output directory or remove it")
    clock = SimClock(start_ns)
    with BagWriter(bag_dir) as bag:
        for topic, type_name, _items in streams:
            bag.add_topic(topic, type_name)
            clock.add_topic(topic, type_name)
        encode = {type_name: (codec(type_name).encode, lite_class(type_name)) for _t, type_name, _i in streams}
        rows = sorted(
            (
                (item.t_ns, topic != TRUTH_TOPIC, n, topic, type_name, item)
                for topic, type_name, items in streams
                for n, item in enumerate(items)
            ),
            key=lambda r: r[:3],
        )
        for *_key, topic, type_name, item in rows:
            enc, cls = encode[type_name]
            data = serialize(type_name, enc(item, cls))
            log = clock.log_time_ns(topic, data)
            bag.write(topic, data, log, log)
    Path(bag_dir, "run_config.yaml").write_text(yamlio.dump(run, sort_keys=False))
