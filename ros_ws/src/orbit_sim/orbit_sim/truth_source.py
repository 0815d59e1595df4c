"""The truth node's core: the scenario's ground truth (orbit_sim.truth), one sample per lock-step.

Registered as the node kind ``truth`` (role ``source``); the engine's source shell publishes each sample on
``/truth/state`` (bench_msgs/TruthState, labelled components, frame in header.frame_id) with /clock. The
trajectory is computed (and scipy loaded: orbit_sim.cowell) only when the source is built: every node reads the
kind.
"""

from __future__ import annotations

from bench_engine import plugins
from bench_engine.graph import CLOCK_TOPIC, CLOCK_TYPE, TRUTH_TOPIC, TRUTH_TYPE, NodeKind, NodeSpec
from bench_engine.stage import Outputs, TruthSample
from orbit_sim.truth import build_truth, read_truth


class TruthSource:
    """Publishes the precomputed truth trajectory, step by step."""

    def __init__(self, cfg: dict, name: str = "truth", run: dict | None = None) -> None:
        self.truth = build_truth(cfg)
        self.steps = self.truth.grid.steps
        self._labels = list(self.truth.labels)

    def t_ns(self, k: int) -> int:
        return self.truth.grid.t_ns(k)

    def outputs(self, k: int) -> Outputs:
        return [(TRUTH_TOPIC, TruthSample(k, self.t_ns(k), self.truth.frame, self._labels, self.truth.states[k]))]


def _spec(cfg: dict, name: str) -> NodeSpec:
    """/truth/state and /clock; the state's labels are the truth model's (its standard views: bench_engine.views)."""
    labels = {TRUTH_TOPIC: plugins.load("truth_models", read_truth(cfg).model).labels} if cfg.get("truth") else {}
    return NodeSpec(name, "truth", publishes={TRUTH_TOPIC: TRUTH_TYPE, CLOCK_TOPIC: CLOCK_TYPE}, labels=labels)


TRUTH = NodeKind(
    "truth",
    "source",
    "bench_engine.source_node:CoreSourceNode",
    instances=lambda cfg, requested: ["truth"],
    spec=_spec,
    check=lambda cfg, name: TruthSource(cfg),
    stage=TruthSource,
)
