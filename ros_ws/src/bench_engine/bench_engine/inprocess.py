"""One run of a scenario's graph in this process, without ROS: the same cores, the same items, the same seeds.

The nodes of a run are rclpy-free cores (bench_engine.stage) behind generic ROS shells; this module drives
those cores directly: the source's items of each step flow through the graph's subscriptions in topological
order, breadth first, in the order the lock-step graph delivers them. Studies, tests
and benchmarks use it instead of hand-written truth -> sensor -> filter loops, and a test checks that it
produces the same items as a run through ROS 2.

    run = run_in_process(load_scenario(name), ["ekf", "ukf"], seed=3)
    run.items["/ekf/estimate"]      # [Estimate, ...] in publication order
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

from bench_engine.graph import CLOCK_TOPIC, Graph, build_graph, node_kinds, resolve_estimators
from bench_engine.parameters import node_settings
from bench_engine.scenario import scenario_seed
from bench_engine.stage import Item, Log
from bench_engine.views import SWITCH as VIEWS_SWITCH


@dataclass
class InProcessRun:
    graph: Graph
    items: dict[str, list[Item]] = field(default_factory=dict)
    """Data topic (not /clock) -> every item published on it, in order."""
    logs: list[tuple[str, str, str]] = field(default_factory=list)
    """(node, level, text) of everything the cores logged."""


def _collector(run: InProcessRun, node: str) -> Log:
    return lambda level, text: run.logs.append((node, level, text))


def run_in_process(
    cfg: dict,
    estimators: list[str] | None = None,
    seed: int | None = None,
    until_step: int | None = None,
    roles: tuple[str, ...] = ("sensor", "estimator"),
) -> InProcessRun:
    """Run ``cfg`` (a resolved scenario) with ``estimators`` (default: its own selection) and ``seed``
    (default: the scenario's) up to step ``until_step`` (default: the last). ``roles=("sensor",)`` runs the
    truth and the sensors only (the measurements, without estimators)."""
    if seed is not None:
        cfg = {**cfg, "seed": int(seed)}
    # no ROS, so no standard views (bench_engine.views: the shells' by-products of the cores' items)
    graph = build_graph({**cfg, VIEWS_SWITCH: False}, resolve_estimators(cfg, estimators), record=False)
    run = InProcessRun(graph, {t: [] for t in graph.data_topics() if t != CLOCK_TOPIC})
    context = {"scenario": cfg, "seed": scenario_seed(cfg)}
    kinds = node_kinds()
    source_spec = graph.of_role("source")[0]
    source = kinds[source_spec.kind].stage(
        node_settings(cfg, source_spec.kind, source_spec.name), source_spec.name, context
    )
    stages, subscribers = {}, {}
    for spec in graph.topological():
        if spec.role in roles:
            stages[spec.name] = kinds[spec.kind].stage(node_settings(cfg, spec.kind, spec.name), spec.name, context)
            stages[spec.name].log = _collector(run, spec.name)
            for topic in spec.subscribes:
                subscribers.setdefault(topic, []).append(spec.name)
    last = source.steps - 1 if until_step is None else min(until_step, source.steps - 1)
    for k in range(last + 1):
        pending = deque(source.outputs(k))
        while pending:
            topic, item = pending.popleft()
            run.items.setdefault(topic, []).append(item)
            for name in subscribers.get(topic, ()):
                pending.extend(stages[name].on_input(topic, item))
    return run
