"""What flows between the nodes of a run, as plain Python objects, and the core every node drives.

A node's behaviour is a :class:`Stage` (sensors, estimators) or a :class:`Source` (the truth): plain objects
that never import rclpy. The ROS shell (bench_engine.stage_node, bench_engine.source_node) decodes each
message into an item with the codec registered for its type (entry-point group ``tracking_bench.codecs``),
calls the core and publishes what it returns; the in-process runner (bench_engine.inprocess) calls the same
cores without ROS. Items carry the lock-step index ``step`` and the sim time ``t_ns`` of the truth sample
they descend from, and their frame.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from bench_engine import plugins

Log = Callable[[str, str], None]
"""log(level, text), level "info", "warning" or "error"."""


def python_log(name: str) -> Log:
    """A Log writing to the Python logger ``name`` (in-process runs; nodes log through rclpy)."""
    logger = logging.getLogger(name)
    return lambda level, text: getattr(logger, level)(text)


@dataclass
class Item:
    step: int
    t_ns: int
    frame_id: str

    @property
    def t(self) -> float:
        """Sim time [s] as a header stamp gives it: sec + nanosec * 1e-9."""
        sec, nanosec = divmod(int(self.t_ns), 1_000_000_000)
        return sec + nanosec * 1e-9


@dataclass
class TruthSample(Item):
    """The true state of step ``step`` (``labels`` name its components)."""

    labels: list[str] = field(default_factory=list)
    state: np.ndarray = field(default_factory=lambda: np.zeros(0))


@dataclass
class Measurement(Item):
    """One measurement vector z with its noise covariance R, from sensor ``source``."""

    source: str = ""
    z: np.ndarray = field(default_factory=lambda: np.zeros(0))
    R: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    labels: list[str] = field(default_factory=list)


@dataclass
class DetectionSet(Item):
    """Every detection of sensor ``source`` at one step (true ones and clutter, unlabelled): Z (N, d) with
    covariances R (N, d, d). Trackers associate them (tracker_filters.association)."""

    source: str = ""
    labels: list[str] = field(default_factory=list)
    Z: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    R: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)))


@dataclass
class Estimate(Item):
    """A state estimate x with covariance P from estimator ``source``, with its NIS and diagnostics."""

    source: str = ""
    labels: list[str] = field(default_factory=list)
    x: np.ndarray = field(default_factory=lambda: np.zeros(0))
    P: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    nis: float = float("nan")
    diagnostics: dict[str, float] = field(default_factory=dict)


Outputs = list[tuple[str, Item]]


class Stage(Protocol):
    """The core of a sensor or estimator node: one input item in, the items to publish out."""

    log: Log

    def on_input(self, topic: str, item: Item) -> Outputs:
        """React to one item received on ``topic``; return (topic, item) pairs to publish, in order."""


class Source(Protocol):
    """The core of the pacing source: the run's steps and what each publishes."""

    steps: int

    def outputs(self, k: int) -> Outputs:
        """Items of step k (the truth sample), published in order; the shell adds /clock."""

    def t_ns(self, k: int) -> int:
        """Sim time of step k [ns]."""


class Codec(Protocol):
    """Converts between a ROS message type and its item (registered per type name). A measurement codec may
    also read a whole topic's measurement vectors at once, ``measurement_vectors(table) -> (N, d) array or
    None`` (a bench_engine.columns.Table; None when they cannot be read as columns), which the scorer uses
    instead of decoding every message."""

    def encode(self, item: Item, msg_type: type) -> object: ...

    def decode(self, msg: object) -> Item: ...


def codec(type_name: str) -> Codec:
    """The codec registered for a ROS message type ("pkg/msg/Type", registered as "pkg.msg.Type")."""
    return plugins.load("codecs", type_name.replace("/", "."))


def set_stamp(msg, item: Item) -> None:
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(item.t_ns), 1_000_000_000)
    msg.header.frame_id = item.frame_id
    msg.step = int(item.step)


def stamp_ns(msg) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


class TruthCodec:
    """bench_msgs/TruthState <-> TruthSample."""

    def encode(self, item: TruthSample, msg_type: type):
        msg = msg_type()
        set_stamp(msg, item)
        msg.labels = list(item.labels)
        msg.state = np.asarray(item.state, dtype=float).tolist()
        return msg

    def decode(self, msg) -> TruthSample:
        return TruthSample(
            msg.step, stamp_ns(msg), msg.header.frame_id, list(msg.labels), np.asarray(msg.state, dtype=float)
        )


class EstimateCodec:
    """bench_msgs/StateEstimate <-> Estimate."""

    def encode(self, item: Estimate, msg_type: type):
        msg = msg_type()
        set_stamp(msg, item)
        msg.filter_name = item.source
        msg.labels = list(item.labels)
        msg.state = np.asarray(item.x, dtype=float).tolist()
        msg.covariance = np.asarray(item.P, dtype=float).ravel().tolist()
        msg.nis = float(item.nis)
        msg.diagnostic_names = list(item.diagnostics)
        msg.diagnostic_values = [float(v) for v in item.diagnostics.values()]
        return msg

    def decode(self, msg) -> Estimate:
        n = len(msg.labels)
        return Estimate(
            msg.step,
            stamp_ns(msg),
            msg.header.frame_id,
            msg.filter_name,
            list(msg.labels),
            np.asarray(msg.state, dtype=float),
            np.asarray(msg.covariance, dtype=float).reshape(n, n),
            float(msg.nis),
            dict(zip(msg.diagnostic_names, msg.diagnostic_values)),
        )


TRUTH_CODEC = TruthCodec()
ESTIMATE_CODEC = EstimateCodec()
