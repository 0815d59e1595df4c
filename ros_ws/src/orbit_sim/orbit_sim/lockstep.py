"""Credit-based lock-step pacing: the source advances only as fast as its slowest consumer.

The pacing source (truth propagator or bag player) publishes step k. Each sensor acknowledges every step
with the cumulative number of measurements it has published; each filter acknowledges every measurement
it consumed with its cumulative count. The source may publish step k when every sensor has acknowledged
step k - 1 - ``window`` and no filter is more than ``window`` measurements behind. ``window = 0`` is
strict lock-step; a small window lets the processes of the graph work in parallel. Nothing is ever
dropped: the window only bounds how far the source runs ahead. When the source publishes the measurements
itself (bag replay, ``sensor_acks=False``) it counts them with :meth:`Pacer.on_published`.

Acknowledgements are cumulative, so a node may hold some back: with W > 0 each node sends one once its step
or count has advanced by W // 4, and any held-back one within 10 ms (orbit_sim.bench_node.BenchNode.ack).
The source then sees the consumers at most W // 4 behind their true progress and never stalls for long.
"""
from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Pacer:
    sensors: list[str]
    filter_inputs: dict[str, list[str]]  # filter -> sensors it consumes
    window: int = 0
    sensor_acks: bool = True
    sensor_step: dict[str, int] = field(default_factory=dict)
    published: dict[str, int] = field(default_factory=dict)
    consumed: dict[str, int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.window < 0:
            raise ValueError(f"pacing window must be >= 0, got {self.window}")
        for s in self.sensors:
            self.sensor_step.setdefault(s, -1)
            self.published.setdefault(s, 0)
        for f, inputs in self.filter_inputs.items():
            unknown = [s for s in inputs if s not in self.published]
            if unknown:
                raise ValueError(f"filter {f} consumes unknown sensor(s) {unknown}")
            self.consumed.setdefault(f, 0)

    def on_ack(self, node: str, step: int, count: int) -> None:
        """Record an acknowledgement; unknown nodes (e.g. from another run) are ignored."""
        if node in self.sensor_step:
            self.sensor_step[node] = max(self.sensor_step[node], step)
            self.published[node] = max(self.published[node], count)
        elif node in self.consumed:
            self.consumed[node] = max(self.consumed[node], count)

    def on_published(self, sensor: str, count: int = 1) -> None:
        """The source itself published ``count`` measurements of ``sensor`` (bag replay)."""
        self.published[sensor] += count

    def backlog(self, filter_name: str) -> int:
        """Measurements published to a filter that it has not yet acknowledged."""
        return sum(self.published[s] for s in self.filter_inputs[filter_name]) - self.consumed[filter_name]

    def can_publish(self, step: int) -> bool:
        """Whether step ``step`` may be published now."""
        if self.sensor_acks and any(acked < step - 1 - self.window for acked in self.sensor_step.values()):
            return False
        return all(self.backlog(f) <= self.window for f in self.filter_inputs)

    def complete(self, last_step: int) -> bool:
        """Every sensor handled ``last_step`` and every filter consumed all it was sent."""
        return ((not self.sensor_acks or all(acked >= last_step for acked in self.sensor_step.values()))
                and all(self.backlog(f) == 0 for f in self.filter_inputs))
