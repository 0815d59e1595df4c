"""The names of a run's topics and the shape of a node's declaration, below the graph and the standard views.

:class:`NodeSpec` is what a node kind declares of one node (its topics and their types); the constants and
functions name the topics the engine and the scorer rely on (the topic contract: MEASUREMENT, ESTIMATE).
bench_engine.graph builds the run's graph from NodeSpecs and re-exports these names, its callers' usual import.
"""

from __future__ import annotations

from dataclasses import dataclass, field

TRUTH_TOPIC = "/truth/state"
CLOCK_TOPIC = "/clock"
ACK_TOPIC = "/sim/ack"
READY_TOPIC = "/sim/ready"
DONE_TOPIC = "/sim/done"
TOTALS_TOPIC = "/sim/totals"
"""The source's last word (StepAck, transient-local, before /sim/done): every data topic's final message count,
so the recorder closes the bag as soon as it holds them all."""

TRUTH_TYPE = "bench_msgs/msg/TruthState"
CLOCK_TYPE = "rosgraph_msgs/msg/Clock"
ESTIMATE_TYPE = "bench_msgs/msg/StateEstimate"
ACK_TYPE = "bench_msgs/msg/StepAck"

MEASUREMENT = "measurement"
ESTIMATE = "estimate"
"""Topic contract, checked by :func:`build_graph` and relied on by the scorer (:func:`topic_owner`): the only
topics named ``/NAME/measurement`` are sensor NAME's measurements (published by that sensor-role node, or by the
player on replay), and the only topics named ``/NAME/estimate`` are estimator NAME's ``StateEstimate``s."""


def measurement_topic(sensor: str) -> str:
    return f"/{sensor}/{MEASUREMENT}"


def estimate_topic(node: str) -> str:
    return f"/{node}/{ESTIMATE}"


def topic_owner(topic: str, suffix: str) -> str | None:
    """NAME if ``topic`` is ``/NAME/<suffix>`` (suffix MEASUREMENT or ESTIMATE), else None."""
    parts = topic.split("/")
    return parts[1] if len(parts) == 3 and not parts[0] and parts[1] and parts[2] == suffix else None


@dataclass
class NodeSpec:
    """One node of the run: its name, kind, role, ROS node class and data topics ({topic: type})."""

    name: str
    kind: str
    role: str = ""
    node: str = ""
    """``module:Class`` of the node, in the package that registers the kind."""
    publishes: dict[str, str] = field(default_factory=dict)
    subscribes: dict[str, str] = field(default_factory=dict)
    """Topic -> type; a kind may leave the type empty, the graph fills it from the topic's publisher."""
    labels: dict[str, tuple[str, ...]] = field(default_factory=dict)
    """Published topic -> the state labels of its items, where the kind knows them: a topic gets the standard
    views its state supports (bench_engine.views); one without labels here gets every view of its type."""
