"""Credit-based lock-step pacing over any acyclic pipeline: the source runs at most W messages ahead.

The pacing source (truth propagator or bag player) publishes step k. Every paced node (sensors and
estimators, any number of stages deep) acknowledges with the cumulative number of data messages it has
consumed and, per topic it publishes, the cumulative number it has published. A node's backlog is what its
input topics have published minus what it has consumed; the source may publish the next step when no
node's backlog exceeds the window W, and the run is complete when every backlog is zero once the source
has published its last step. ``W = 0`` is strict lock-step. Nothing is ever dropped: the window only
bounds how far the source runs ahead.

Completeness holds for any acyclic chain: a node's acknowledgement reports its published counts as of the
inputs it has consumed, so when every backlog is zero, every stage has consumed everything its (finished)
upstream stages published. For a sensor fed by the truth (one message per step) the rule is "every sensor
has handled step k - 1 - W"; for an estimator it bounds the unprocessed measurements.

Acknowledgements are cumulative, so a node may hold some back: with W > 0 each node sends one once its step
or count has advanced by W // 4, and any held-back one within 10 ms (bench_engine.bench_node.BenchNode.ack).
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Pacer:
    inputs: dict[str, list[str]]
    """Paced node -> the topics it consumes."""
    window: int = 0
    published: dict[str, int] = field(default_factory=dict)
    """Topic -> cumulative messages published (the source's own, counted by it; the others from acks)."""
    consumed: dict[str, int] = field(default_factory=dict)
    weights: dict[str, int] = field(default_factory=dict)
    """Paced node -> its window in units of ``window`` (default 1; the recorder reads every topic)."""

    def __post_init__(self) -> None:
        if self.window < 0:
            raise ValueError(f"pacing window must be >= 0, got {self.window}")
        for node, topics in self.inputs.items():
            self.consumed.setdefault(node, 0)
            for topic in topics:
                self.published.setdefault(topic, 0)

    def on_ack(self, node: str, consumed: int, published: dict[str, int]) -> None:
        """Record an acknowledgement; unknown nodes (e.g. from another run) are ignored."""
        if node not in self.consumed:
            return
        self.consumed[node] = max(self.consumed[node], consumed)
        for topic, count in published.items():
            if topic in self.published:
                self.published[topic] = max(self.published[topic], count)

    def on_published(self, topic: str, count: int = 1) -> None:
        """The source itself published ``count`` messages on ``topic``."""
        if topic in self.published:
            self.published[topic] += count

    def backlog(self, node: str) -> int:
        """Messages published to ``node`` that it has not yet acknowledged."""
        return sum(self.published[t] for t in self.inputs[node]) - self.consumed[node]

    def can_publish(self) -> bool:
        """Whether the source may publish its next step now."""
        return all(self.backlog(n) <= self.window * self.weights.get(n, 1) for n in self.inputs)

    def complete(self) -> bool:
        """Every paced node consumed all it was sent (call once the source has published its last step)."""
        return all(self.backlog(n) == 0 for n in self.inputs)
