"""Derived measurements: a stage between sensors and filters that turns measurements into new ones,
registered as the node kind ``derived`` (role sensor) for every entry of the scenario's
``derived_measurements`` section. A filter lists a derived measurement in its ``sensors`` like a sensor.

    derived_measurements:
      gnss_baseline:                  # baseline r2 - r1 from two receivers' fixes of the same step
        type: difference
        of: [gnss2, gnss1]
        labels: [bx, by, bz]          # the state components the result measures
      gnss_baseline_pv:               # positions plus numerically differentiated velocities (paper 002, eq. 29)
        type: differentiated
        of: gnss_baseline
        order: 4                      # degree of Newton's interpolating polynomial (window order + 1 samples)
        labels: [bx, by, bz, bvx, bvy, bvz]

``difference``: z = z_a - z_b, R = R_a + R_b (independent sensors), published when both of a step arrived.
``differentiated``: the centre sample's position with the derivative of Newton's polynomial through the
centred window (tracker_filters.differentiation); R is propagated through the linear weights, including the
position-velocity covariance. It is published when the window's last sample arrives, stamped with the centre
sample's step and time: a lag of order / 2 samples; the last order / 2 samples of a run get no velocity. The
overlapping windows make successive derived measurements correlated, which a filter cannot know: the
reason paper 002's variant (b) can lose to (a).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from bench_engine.config import ScenarioError
from bench_engine.graph import NodeKind, NodeSpec, measurement_topic
from bench_engine.settings import (
    POSITIVE,
    Check,
    NoKeys,
    SectionReader,
    Settings,
    at_least,
    read_entries,
    setting,
    variant,
)
from bench_engine.stage import Measurement, Outputs, python_log
from bench_models.labelled import ComponentModel

SECTION = "derived_measurements"
TYPES = ("difference", "differentiated")
VECTOR_TYPE = "bench_msgs/msg/VectorMeasurement"


@dataclass(frozen=True, kw_only=True)
class Differentiated(Settings):
    """``differentiated``: positions with Newton velocities over a centred window."""

    order: int = setting(
        4, doc="degree of Newton's interpolating polynomial (order + 1 samples a window)", check=at_least(1)
    )
    max_gap: float = setting(float("inf"), unit="s", doc="no window spans a gap longer than this", check=POSITIVE)


KINDS = {"difference": NoKeys, "differentiated": Differentiated}


@dataclass(frozen=True, kw_only=True)
class DerivedConfig(Settings):
    """One entry of ``derived_measurements`` (the module docstring)."""

    type: str = setting(
        choices=TYPES,
        doc="difference: z_a - z_b of one step; differentiated: positions with their numerical velocities",
    )
    of: str | list[str] = setting(
        doc="the sensors or earlier derived measurements it derives from: two for a "
        "difference ([a, b]: a - b), one to differentiate"
    )
    labels: list[str] = setting(
        doc="the state components the result measures", check=Check(bool, "a non-empty list of state labels")
    )
    options: Settings = variant("type", lambda: TYPES, KINDS.get)

    @property
    def sources(self) -> tuple[str, ...]:
        return (self.of,) if isinstance(self.of, str) else tuple(self.of)


def read_derived(cfg: dict) -> dict[str, DerivedConfig]:
    """The ``derived_measurements`` section, read strictly. Each entry's ``of`` names sensors or derived
    measurements listed before it."""
    out = read_entries(DerivedConfig, cfg.get(SECTION), SECTION)
    known = list((cfg.get("sensors") or {}).keys())
    for name, conf in out.items():
        need = 2 if conf.type == "difference" else 1
        if len(conf.sources) != need or any(s not in known for s in conf.sources):
            raise ScenarioError(
                f"'{conf.where('of')}' must name {need} of the sensors or earlier derived "
                f"measurements {known}, got {list(conf.sources)}"
            )
        known.append(name)
    return out


DERIVED_MEASUREMENTS = SectionReader(
    SECTION,
    dict[str, DerivedConfig],
    "measurements derived from others between "
    "sensors and filters (node kind derived); a filter lists them in its sensors",
    read_derived,
)


def derived_config(cfg: dict, name: str) -> DerivedConfig:
    derived = read_derived(cfg)
    if name not in derived:
        raise ScenarioError(f"unknown derived measurement '{name}'; the scenario has: {sorted(derived)}")
    return derived[name]


@dataclass
class DerivedSource:
    """What a filter needs of a derived measurement: its model (bound to the filter's state by ``bind``)."""

    name: str
    model: ComponentModel

    def bind(self, state_labels: list[str]) -> None:
        self.model = self.model.for_state(state_labels)


def derived_source(cfg: dict, name: str) -> DerivedSource:
    return DerivedSource(name, ComponentModel(derived_config(cfg, name).labels))


class DifferenceStage:
    """z_a - z_b of the same step."""

    def __init__(self, name: str, conf: DerivedConfig) -> None:
        self.name, self.conf = name, conf
        self.pending: dict[str, dict[int, Measurement]] = {s: {} for s in conf.sources}

    def on_input(self, topic: str, m: Measurement) -> Outputs:
        source = topic.split("/")[1]
        self.pending[source][m.step] = m
        a, b = (self.pending[s] for s in self.conf.sources)
        if m.step not in a or m.step not in b:
            return []
        ma, mb = a[m.step], b[m.step]
        for buffer in (a, b):  # each sensor publishes in step order: older unpaired steps can never pair
            for step in [k for k in buffer if k <= m.step]:
                del buffer[step]
        if ma.z.shape != mb.z.shape or len(ma.z) != len(self.conf.labels):
            raise ValueError(
                f"derived measurement '{self.name}': {list(self.conf.sources)} give {len(ma.z)} and "
                f"{len(mb.z)} components, labels {list(self.conf.labels)}"
            )
        return [
            (
                measurement_topic(self.name),
                Measurement(m.step, m.t_ns, ma.frame_id, self.name, ma.z - mb.z, ma.R + mb.R, list(self.conf.labels)),
            )
        ]


class DifferentiatedStage:
    """Centre position and Newton derivative over a sliding window of order + 1 samples."""

    def __init__(self, name: str, conf: DerivedConfig) -> None:
        from tracker_filters.differentiation import weights_at_node  # scipy: only where a derivative is taken

        self.name, self.conf, self.weights = name, conf, weights_at_node
        self.max_gap_ns = conf.options.max_gap * 1e9
        self.window: deque[Measurement] = deque(maxlen=conf.options.order + 1)

    def on_input(self, topic: str, m: Measurement) -> Outputs:
        if self.window and m.t_ns - self.window[-1].t_ns > self.max_gap_ns:
            self.window.clear()  # never difference across a data gap
        self.window.append(m)
        if len(self.window) < self.window.maxlen:
            return []
        centre = self.window[len(self.window) // 2]
        w = self.weights(np.array([m.t_ns for m in self.window]) * 1e-9, len(self.window) // 2)
        d = len(centre.z)
        if 2 * d != len(self.conf.labels):
            raise ValueError(
                f"derived measurement '{self.name}' differentiates {d} components into "
                f"{len(self.conf.labels)} labels (need {2 * d})"
            )
        v = np.einsum("k,kd->d", w, np.array([s.z for s in self.window]))
        R_vel = np.einsum("k,kij->ij", w * w, np.array([s.R for s in self.window]))
        R = np.block([[centre.R, w[len(w) // 2] * centre.R], [w[len(w) // 2] * centre.R, R_vel]])
        return [
            (
                measurement_topic(self.name),
                Measurement(
                    centre.step,
                    centre.t_ns,
                    centre.frame_id,
                    self.name,
                    np.concatenate([centre.z, v]),
                    R,
                    list(self.conf.labels),
                ),
            )
        ]


def build_stage(cfg: dict, name: str, run: dict | None = None):
    conf = derived_config(cfg, name)
    stage = (DifferenceStage if conf.type == "difference" else DifferentiatedStage)(name, conf)
    stage.log = python_log(name)
    return stage


def _spec(cfg: dict, name: str) -> NodeSpec:
    conf = derived_config(cfg, name)
    return NodeSpec(
        name,
        "derived",
        publishes={measurement_topic(name): VECTOR_TYPE},
        subscribes={measurement_topic(s): "" for s in conf.sources},
    )


DERIVED = NodeKind(
    "derived",
    "sensor",
    "bench_engine.stage_node:StageNode",
    instances=lambda cfg, requested: list(read_derived(cfg)),
    spec=_spec,
    check=lambda cfg, name: derived_config(cfg, name),
    stage=build_stage,
    order=1,
)
