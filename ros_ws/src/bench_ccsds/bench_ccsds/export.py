"""Any bag to CCSDS Navigation Data Messages: each estimator's track and the truth as an OEM, each sensor's
measurements as a TDM.

What maps, and what has no CCSDS keyword (said in the export's summary and in the messages' comments):
- **OEM** (bench_ccsds.oem): a state with components ``x y z vx vy vz`` (optionally ``ax ay az``), or one such
  group per satellite (``x1 … vz1``, ``x2 …``: one segment each), in frame ``eci`` (REF_FRAME TEME, CENTER_NAME
  EARTH: bench_ccsds.epochs). An estimate's covariance block of the group is a COVARIANCE_START block at its
  epoch; the truth has none. States in ``lvlh`` (a deputy relative to its chief), baselines, biases and
  attitudes have no OEM frame or keyword and are not exported.
- **TDM** (bench_ccsds.tdm): a ``bench_msgs/RangeAzEl`` sensor in a station frame (``*_enu``: ground radar) gives
  RANGE, ANGLE_1 / ANGLE_2 (ANGLE_TYPE AZEL) and DOPPLER_INSTANTANEOUS (its range rate, when it has one); an
  inter-satellite RangeAzEl (frame ``lvlh``) gives RANGE and DOPPLER_INSTANTANEOUS only: its angles are in the
  chief's LVLH axes, which no TDM ANGLE_TYPE names. A ``bench_msgs/VectorMeasurement`` gives its ``range`` and
  ``range_rate`` components (e.g. GRACE's K-band range rate); positions and baselines have no TDM keyword.
  Noise covariances are not part of a TDM: the scenario (in the bag) holds them.

Values are written with 17 significant digits in the CCSDS units (km, km/s, deg): read back and converted to SI
they are the bag's to within one or two units in the last place (tests/test_ccsds_orekit.py checks Orekit reads
them so). Epochs are UTC to the nanosecond (the bag's stamps) on the run's time line (bench_ccsds.epochs).
"""

from __future__ import annotations

import re
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench_ccsds.epochs import TIME_SYSTEM, RunTime, ccsds_frame, run_time
from bench_ccsds.kvn import epoch_text
from bench_ccsds.oem import Segment, write_oem
from bench_ccsds.tdm import TdmSegment, write_tdm
from bench_engine.bag_reader import BagReader
from bench_engine.config import ScenarioError
from bench_engine.graph import ESTIMATE, ESTIMATE_TYPE, MEASUREMENT, TRUTH_TOPIC, topic_owner
from bench_engine.labels import ORBIT
from bench_engine.stage import codec
from bench_eval.cli.replay import recorded_run

ORIGINATOR = "TRACKING-BENCH"
ACCELERATION = ("ax", "ay", "az")
TDM_COMPONENTS = {"range": "RANGE", "range_rate": "DOPPLER_INSTANTANEOUS"}
"""VectorMeasurement components with a TDM keyword."""


@dataclass
class Export:
    """What an export wrote (path -> one line on its content) and what it left out (source -> why)."""

    written: dict[Path, str] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)

    def summary(self) -> str:
        lines = [f"wrote {path}: {what}" for path, what in self.written.items()]
        lines += [f"not exported: {name}: {why}" for name, why in self.skipped.items()]
        return "\n".join(lines)


def export_bag(
    bag_dir: str | Path, out_dir: str | Path, estimators: list[str] | None = None, truth: bool = True
) -> Export:
    """Write ``out_dir/NAME.oem`` for the truth and every estimator (or those named) and ``out_dir/SENSOR.tdm``
    for every sensor of the bag whose content CCSDS can hold; returns what was written and what was not."""
    bag_dir, out_dir = Path(bag_dir), Path(out_dir)
    run = recorded_run(bag_dir)
    cfg = run["scenario"]
    clock = run_time(cfg)
    reader = BagReader(bag_dir)
    types = reader.topics()
    sources = _sources(types, estimators, truth)
    if estimators:
        unknown = sorted(set(estimators) - {name for name, *_ in sources})
        if unknown:
            raise ScenarioError(
                f"no estimates of {unknown} in {bag_dir}; it has "
                f"{sorted(n for n, _t, kind in sources if kind == 'estimate')}"
            )
    tables = reader.tables([topic for _name, topic, _kind in sources])
    out_dir.mkdir(parents=True, exist_ok=True)
    result = Export()
    created = time.time_ns()
    header = [
        f"exported by the tracking bench from the bag {bag_dir.resolve()}",
        f"scenario {cfg.get('scenario')}, seed {run.get('seed')}; {clock.note()}",
    ]
    target = _target(cfg)
    for name, topic, kind in sources:
        if topic not in tables:
            result.skipped[name] = "no messages in the bag"
            continue
        items = [codec(types[topic]).decode(tables[topic].row(i)) for i in range(len(tables[topic]))]
        if kind == "measurement":
            _export_measurements(name, items, out_dir, clock, target, created, header, result)
        else:
            if kind == "estimate":
                items = [item for item in items if item.source == name]
            _export_states(name, items, kind, out_dir, clock, target, created, header, result)
    return result


def _sources(types: dict[str, str], estimators: list[str] | None, truth: bool) -> list[tuple[str, str, str]]:
    """(name, topic, kind) of the bag's truth, estimates and measurements."""
    out = [("truth", TRUTH_TOPIC, "truth")] if truth and TRUTH_TOPIC in types else []
    for topic, type_name in sorted(types.items()):
        owner = topic_owner(topic, ESTIMATE)
        if owner is not None and type_name == ESTIMATE_TYPE and (not estimators or owner in estimators):
            out.append((owner, topic, "estimate"))
        sensor = topic_owner(topic, MEASUREMENT)
        if sensor is not None:
            out.append((sensor, topic, "measurement"))
    return out


def _target(cfg: dict) -> tuple[str, str]:
    """(OBJECT_NAME, OBJECT_ID) of the tracked object: a TLE's title and international designator, else the
    scenario's name."""
    truth = cfg.get("truth") if isinstance(cfg.get("truth"), dict) else {}
    tle = truth.get("tle")
    if truth.get("model") == "sgp4" and isinstance(tle, list) and len(tle) >= 2 and isinstance(tle[-2], str):
        line1 = tle[-2]
        designator = line1[9:17].strip()
        title = tle[0].strip() if len(tle) == 3 and isinstance(tle[0], str) else f"NORAD {line1[2:7].strip()}"
        if re.fullmatch(r"\d{5}[A-Z]{1,3}", designator):
            year = int(designator[:2])
            designator = f"{1900 + year if year >= 57 else 2000 + year}-{designator[2:]}"
        return title, designator or line1[2:7].strip()
    name = str(cfg.get("scenario", "bench"))
    return f"{name} target", name


def _groups(labels: list[str]) -> dict[str, list[int]]:
    """Satellite suffix ("" or "1", "2", ...) -> indices of x y z vx vy vz (+ ax ay az) in ``labels``."""
    groups = {}
    for suffix in dict.fromkeys(re.sub(r"^[a-z]+", "", lab) for lab in labels):
        names = [c + suffix for c in ORBIT]
        if all(n in labels for n in names):
            accel = [c + suffix for c in ACCELERATION]
            groups[suffix] = [labels.index(n) for n in names + (accel if all(a in labels for a in accel) else [])]
    return groups


def _export_states(
    name: str,
    items: list,
    kind: str,
    out_dir: Path,
    clock: RunTime,
    target: tuple[str, str],
    created: int,
    header: list[str],
    result: Export,
) -> None:
    items = sorted(items, key=lambda item: item.t_ns)
    labels = list(items[0].labels)
    frame = ccsds_frame(items[0].frame_id)
    groups = _groups(labels)
    if frame is None:
        result.skipped[name] = (
            f"states in frame '{items[0].frame_id}': OEM has no reference frame for it (a deputy "
            "relative to its chief, a star tracker's attitude)"
        )
        return
    if not groups:
        result.skipped[name] = f"state {labels} has no x y z vx vy vz: nothing an OEM holds"
        return
    times = [clock.utc(item.t_ns) for item in items]
    if any(b <= a for a, b in zip(times, times[1:])):
        keep = [0] + [i for i in range(1, len(times)) if times[i] > times[i - 1]]
        items, times = [items[i] for i in keep], [times[i] for i in keep]
    values = np.array([item.state if kind == "truth" else item.x for item in items], dtype=float)
    segments = []
    for suffix, index in groups.items():
        title = target[0] if not suffix else f"{target[0]} {suffix}"
        seg = Segment(
            title,
            target[1] if not suffix else f"{target[1]}-{suffix}",
            frame,
            times,
            values[:, index],
            time_system=TIME_SYSTEM,
        )
        if kind == "estimate":
            pv = index[:6]
            seg.covariances = [(t, item.P[np.ix_(pv, pv)]) for t, item in zip(times, items)]
            seg.comments.append(
                f"estimates of the bench's estimator '{name}' after each measurement, with their covariance"
            )
        else:
            seg.comments.append("the run's truth (the simulated satellite's state at every step)")
            seg.interpolation = ("HERMITE", 5)
        segments.append(seg)
    path = write_oem(out_dir / f"{name}.oem", segments, ORIGINATOR, created, header)
    covs = f", {len(times)} covariances" if kind == "estimate" else ""
    result.written[path] = f"OEM, {len(segments)} segment(s), {len(times)} states{covs}, {frame}, {TIME_SYSTEM}"


def _export_measurements(
    name: str,
    items: list,
    out_dir: Path,
    clock: RunTime,
    target: tuple[str, str],
    created: int,
    header: list[str],
    result: Export,
) -> None:
    first = items[0]
    labels = list(first.labels)
    keywords: dict[str, int] = {}
    comments = []
    if len(labels) >= 3 and labels[:3] == ["range", "azimuth", "elevation"]:
        keywords["RANGE"] = 0
        if first.frame_id.endswith("_enu"):
            keywords.update(ANGLE_1=1, ANGLE_2=2)
        else:
            comments.append(
                f"azimuth and elevation in frame '{first.frame_id}' are not exported: no TDM ANGLE_TYPE "
                "names a spacecraft's LVLH axes"
            )
        if "range_rate" in labels:
            keywords["DOPPLER_INSTANTANEOUS"] = labels.index("range_rate")
    else:
        keywords = {TDM_COMPONENTS[lab]: i for i, lab in enumerate(labels) if lab in TDM_COMPONENTS}
        lost = [lab for lab in labels if lab not in TDM_COMPONENTS]
        if lost:
            comments.append(f"components {lost} are not exported: TDM has no keyword for them")
    if not keywords:
        result.skipped[name] = f"measurements of {labels}: TDM has no keyword for any of them"
        return
    items = sorted(items, key=lambda item: item.t_ns)
    metadata = {
        "TIME_SYSTEM": TIME_SYSTEM,
        "START_TIME": epoch_text(clock.utc(items[0].t_ns)),
        "STOP_TIME": epoch_text(clock.utc(items[-1].t_ns)),
        "PARTICIPANT_1": name,
        "PARTICIPANT_2": target[0],
        "MODE": "SEQUENTIAL",
        "PATH": "1,2,1",
    }
    if "ANGLE_1" in keywords:
        metadata["ANGLE_TYPE"] = "AZEL"
    metadata["RANGE_UNITS"] = "km"
    seg = TdmSegment(
        metadata,
        comments=[
            f"measurements of the bench's sensor '{name}' (frame {first.frame_id}): "
            "geometric values at their time tags, no light time, noise as simulated; "
            "RANGE is the one-way distance",
            *comments,
        ],
    )
    for keyword, index in keywords.items():
        seg.observations[keyword] = [(clock.utc(item.t_ns), float(item.z[index])) for item in items]
    path = write_tdm(out_dir / f"{name}.tdm", [seg], ORIGINATOR, created, header)
    result.written[path] = f"TDM, {', '.join(keywords)}: {len(items)} epochs each, {TIME_SYSTEM}"
    if comments:
        result.skipped[f"{name} (part)"] = "; ".join(comments)
