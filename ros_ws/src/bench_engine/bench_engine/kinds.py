"""The node kinds the run engine itself provides: the recorder and the bag player (replay source)."""

from __future__ import annotations

from bench_engine.graph import CLOCK_TOPIC, CLOCK_TYPE, NodeKind, NodeSpec

RECORDER = NodeKind(
    "recorder",
    "recorder",
    "bench_engine.recorder_node:RecorderNode",
    instances=lambda cfg, requested: ["recorder"],
    spec=lambda cfg, name: NodeSpec(name, "recorder"),
)

PLAYER = NodeKind(
    "player",
    "replay",
    "bench_engine.player_node:PlayerNode",
    instances=lambda cfg, requested: ["player"],
    spec=lambda cfg, name: NodeSpec(name, "player", publishes={CLOCK_TOPIC: CLOCK_TYPE}),
)
