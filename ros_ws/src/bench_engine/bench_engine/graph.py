"""The node graph of a run, built from data: registered node kinds, each instantiated from the scenario.

A node kind (:class:`NodeKind`, registered in the entry-point group ``tracking_bench.node_kinds``) says which
of its instances a scenario holds, what each publishes and subscribes, and how to check its configuration.
:func:`build_graph` asks every registered kind, resolves each subscribed topic to its one publisher, checks
that the data flow is acyclic and adds the recorder. The launcher starts what the graph lists, every node
finds its own topics here, and the readiness barrier uses :meth:`Graph.expected_subscribers`.

Roles: ``source`` paces the run (the truth); ``sensor`` nodes turn the source's output into measurements
(on replay the ``replay`` source publishes their recorded topics instead); ``estimator`` nodes consume
any topics and publish estimates; the ``recorder`` writes every data topic. Sensors and estimators are
paced (bench_engine.lockstep): any acyclic chain of them, e.g. camera -> identifier -> tracker -> attitude.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from bench_engine import plugins
from bench_engine.config import ScenarioError
from bench_engine.scenario import default_estimators
from bench_engine.topics import (  # noqa: F401 - re-exported: the graph is where callers find a run's topics
    ACK_TOPIC,
    ACK_TYPE,
    CLOCK_TOPIC,
    CLOCK_TYPE,
    DONE_TOPIC,
    ESTIMATE,
    ESTIMATE_TYPE,
    MEASUREMENT,
    READY_TOPIC,
    TOTALS_TOPIC,
    TRUTH_TOPIC,
    TRUTH_TYPE,
    NodeSpec,
    estimate_topic,
    measurement_topic,
    topic_owner,
)
from bench_engine.views import add_standard_views

RUN_ONLY_KEYS = ("description", "variants", "sweeps")
"""Scenario keys only the launcher reads (variants and sweeps are resolved before a run): no node's setting."""

ROLES = ("source", "replay", "sensor", "estimator", "recorder")
PACED_ROLES = ("sensor", "estimator", "recorder")
"""Roles whose nodes acknowledge what they consumed, so the source never runs more than the pacing window
ahead of them. The recorder is one: DDS does not hold every message for a subscriber that falls far behind
(a busy recorder was measured losing messages under load), so the source waits for it too."""


@dataclass(frozen=True)
class NodeKind:
    """A registered kind of node. ``instances(cfg, selected)`` names the kind's nodes in a scenario
    (``selected``: the run's selected estimators, see ``claims``); ``spec(cfg, name)`` gives one node's
    :class:`NodeSpec` (topics); ``check(cfg, name)`` builds its core objects once and raises ScenarioError
    naming a bad key; ``stage(cfg, name, run)`` builds the rclpy-free core the node and the in-process
    runner (bench_engine.inprocess) drive."""

    name: str
    role: str
    node: str
    instances: Callable[[dict, list[str]], list[str]]
    spec: Callable[[dict, str], NodeSpec]
    check: Callable[[dict, str], None] | None = None
    stage: Callable[[dict, str, dict], object] | None = None
    order: int = 0
    """Build order among kinds of one role (lower first)."""
    claims: Callable[[dict], list[str]] | None = None
    """For an estimator kind whose nodes a run selects by name (``--estimators``, the scenario's ``estimators``):
    the names its own scenario section defines. Each selected name belongs to the one kind claiming it (or,
    unclaimed, to the kind that ``takes_unclaimed``), and such a kind's ``instances`` receives only its own
    names; a kind that claims nothing receives the whole selection."""
    takes_unclaimed: bool = False
    """This kind owns the selected names no kind claims (the filter kind: a name without a section is a
    filter of that type)."""
    reads: Callable[[dict, str], dict] | None = None
    """``reads(cfg, name)``: the part of the scenario node ``name``'s core reads, which is all it is given (its
    ROS parameters, bench_engine.parameters); None: every key but the launcher's own (RUN_ONLY_KEYS)."""

    def settings(self, cfg: dict, name: str) -> dict:
        """What node ``name`` of this kind is configured with (its parameters, unflattened)."""
        if self.reads is not None:
            return self.reads(cfg, name)
        return {k: v for k, v in cfg.items() if k not in RUN_ONLY_KEYS}


@dataclass
class Graph:
    nodes: list[NodeSpec]

    def node(self, name: str) -> NodeSpec:
        for spec in self.nodes:
            if spec.name == name:
                return spec
        raise KeyError(f"no node '{name}' in this run; nodes: {[n.name for n in self.nodes]}")

    def of_role(self, *roles: str) -> list[NodeSpec]:
        return [n for n in self.nodes if n.role in roles]

    def expected_subscribers(self, topic: str) -> int:
        return sum(topic in n.subscribes for n in self.nodes)

    def data_topics(self) -> dict[str, str]:
        """Every data topic of the run with its type (what the recorder records)."""
        topics: dict[str, str] = {}
        for spec in self.nodes:
            topics.update(spec.publishes)
        return topics

    def paced_inputs(self) -> dict[str, list[str]]:
        """Paced node -> the data topics it consumes (what bench_engine.lockstep.Pacer counts). The recorder's
        /clock is not counted: the source publishes it after each step's data, and it carries none."""
        return {n.name: sorted(t for t in n.subscribes if t != CLOCK_TOPIC) for n in self.of_role(*PACED_ROLES)}

    def pacing_weights(self) -> dict[str, int]:
        """Paced node -> how many windows of backlog it may hold: the recorder reads every data topic, so its
        window is the pacing window times its number of input topics (the others: one)."""
        inputs = self.paced_inputs()
        return {n.name: max(1, len(inputs[n.name])) for n in self.of_role("recorder")}

    def topological(self) -> list[NodeSpec]:
        """Nodes, every publisher before its subscribers (the recorder last)."""
        publisher = {t: n.name for n in self.nodes for t in n.publishes}
        order: list[NodeSpec] = []
        placed: set[str] = set()
        remaining = list(self.nodes)
        while remaining:
            ready = [
                n
                for n in remaining
                if all(publisher.get(t) in placed or publisher.get(t) == n.name for t in n.subscribes)
            ]
            if not ready:
                names = sorted(n.name for n in remaining)
                raise ScenarioError(
                    f"the nodes {names} consume each other's topics in a cycle: the data flow of a run must be acyclic"
                )
            order += ready
            placed.update(n.name for n in ready)
            remaining = [n for n in remaining if n.name not in placed]
        return order

    def start_order(self) -> list[NodeSpec]:
        """Subscribers before their publishers (so nothing is published to nobody), the source last."""
        return list(reversed(self.topological()))


def resolve_estimators(cfg: dict, requested: list[str] | None) -> list[str]:
    """The run's selected estimators, of any kind: ``requested`` (the command line's ``--estimators``), else the
    scenario's ``estimators``, else every estimator a kind's section defines (``NodeKind.claims``)."""
    names = (
        requested
        or default_estimators(cfg)
        or [n for k in node_kinds().values() if k.claims is not None for n in k.claims(cfg)]
    )
    if not names:
        raise ScenarioError("no estimators selected, and the scenario has no 'estimators' and defines none")
    if len(set(names)) != len(names):
        raise ScenarioError(f"estimator names must be unique, got {names}")
    for name in names:
        if not name.replace("_", "").isalnum():
            raise ScenarioError(f"estimator name '{name}' must be letters, digits and underscores")
    return list(names)


def owners(cfg: dict, selected: list[str], kinds: list[NodeKind]) -> dict[str, list[str]]:
    """Kind name -> the selected estimators it owns: each name belongs to the one kind that claims it, or to
    the kind that takes unclaimed names (ScenarioError for a name two kinds claim, or that no kind takes)."""
    claims = {k.name: set(k.claims(cfg)) for k in kinds if k.claims is not None}
    fallback = [k.name for k in kinds if k.name in claims and k.takes_unclaimed]
    owned: dict[str, list[str]] = {kind: [] for kind in claims}
    for name in selected:
        claim = [kind for kind, names in claims.items() if name in names]
        if len(claim) > 1:
            raise ScenarioError(f"estimator '{name}' is defined by more than one kind's section: {claim}")
        if not claim and not fallback:
            raise ScenarioError(f"no section of the scenario defines estimator '{name}'")
        owned[(claim or fallback)[0]].append(name)
    return owned


def node_kinds() -> dict[str, NodeKind]:
    """Every registered node kind by name."""
    return plugins.registered("node_kinds")


def _kind_nodes(kind: NodeKind, cfg: dict, selected: list[str]) -> list[NodeSpec]:
    specs = []
    for name in kind.instances(cfg, selected):
        spec = kind.spec(cfg, name)
        spec.kind, spec.role, spec.node = kind.name, kind.role, kind.node
        specs.append(spec)
    return specs


def build_graph(cfg: dict, estimators: list[str] | None, record: bool = True, source: str = "truth") -> Graph:
    """Nodes of a run: the pacing source (``truth``, or the bag ``player`` on replay), every registered
    sensor-role and estimator-role kind's instances for the selected ``estimators`` (None: the scenario's,
    :func:`resolve_estimators`), and the recorder. Raises ScenarioError for a topic nobody publishes, a topic
    two nodes publish, a duplicate node name or a cycle."""
    kinds = sorted(node_kinds().values(), key=lambda k: (ROLES.index(k.role), k.order, k.name))
    by_name = {k.name: k for k in kinds}
    if source not in by_name or by_name[source].role not in ("source", "replay"):
        sources = [k.name for k in kinds if k.role in ("source", "replay")]
        raise ScenarioError(f"unknown pacing source {source!r}; registered sources: {sources}")
    selected = resolve_estimators(cfg, estimators)
    owned = owners(cfg, selected, [k for k in kinds if k.role == "estimator"])

    def of_role(role: str) -> list[NodeSpec]:
        return [s for k in kinds if k.role == role for s in _kind_nodes(k, cfg, owned.get(k.name, selected))]

    truth, sensors, estimator_nodes = of_role("source"), of_role("sensor"), of_role("estimator")
    if by_name[source].role == "source":
        nodes = [s for s in truth if s.kind == source] + sensors
    else:  # replay: the player publishes what the truth and the sensors recorded
        player = _kind_nodes(by_name[source], cfg, selected)[0]
        for spec in truth + sensors:
            player.publishes.update(spec.publishes)
        nodes = [player]
    nodes += estimator_nodes
    add_standard_views(nodes, cfg)
    _check_topic_contract(nodes)
    _resolve_topics(nodes)
    if record:
        recorder = of_role("recorder")
        for spec in recorder:
            for node in nodes:
                spec.subscribes.update(node.publishes)
        nodes += recorder
    graph = Graph(nodes)
    graph.topological()
    return graph


def _check_topic_contract(nodes: list[NodeSpec]) -> None:
    """Every ``/NAME/measurement`` and ``/NAME/estimate`` topic is what MEASUREMENT and ESTIMATE say it is."""
    for node in nodes:
        for topic, type_name in node.publishes.items():
            sensor, estimator = topic_owner(topic, MEASUREMENT), topic_owner(topic, ESTIMATE)
            if sensor is not None and node.role != "replay" and (sensor != node.name or node.role != "sensor"):
                raise ScenarioError(
                    f"node '{node.name}' ({node.kind}) publishes {topic}: only sensor '{sensor}' "
                    f"may (the topic contract of bench_engine.graph.MEASUREMENT)"
                )
            if estimator is not None and (
                estimator != node.name or node.role != "estimator" or type_name != ESTIMATE_TYPE
            ):
                raise ScenarioError(
                    f"node '{node.name}' ({node.kind}) publishes {topic} as {type_name}: only "
                    f"estimator '{estimator}' may, as {ESTIMATE_TYPE} (bench_engine.graph.ESTIMATE)"
                )


def _resolve_topics(nodes: list[NodeSpec]) -> None:
    names = [n.name for n in nodes]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise ScenarioError(f"node names must be unique across sensors, estimators and stages; repeated: {duplicates}")
    publisher: dict[str, NodeSpec] = {}
    for node in nodes:
        for topic in node.publishes:
            if topic in publisher:
                raise ScenarioError(f"topic {topic} is published by both '{publisher[topic].name}' and '{node.name}'")
            publisher[topic] = node
    for node in nodes:
        for topic in node.subscribes:
            if topic not in publisher:
                source = topic_owner(topic, ESTIMATE)
                hint = f"; select estimator '{source}' too" if source is not None else ""
                raise ScenarioError(
                    f"node '{node.name}' consumes {topic}, which no node of the run publishes"
                    f"{hint}; published topics: {sorted(publisher)}"
                )
            node.subscribes[topic] = publisher[topic].publishes[topic]
