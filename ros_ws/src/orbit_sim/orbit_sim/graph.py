"""The node graph of a run: which nodes exist, what each publishes and subscribes, and who must match whom.

Pure data built from the scenario; the launcher starts what it lists, every node finds its own topics
here, and the readiness barrier uses :meth:`Graph.expected_subscribers` so that no step starts before
every subscriber is connected.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from orbit_sim.config import ScenarioError, Section

TRUTH_TOPIC = "/truth/state"
CLOCK_TOPIC = "/clock"
ACK_TOPIC = "/sim/ack"
READY_TOPIC = "/sim/ready"
DONE_TOPIC = "/sim/done"

TRUTH_TYPE = "bench_msgs/msg/TruthState"
CLOCK_TYPE = "rosgraph_msgs/msg/Clock"
ESTIMATE_TYPE = "bench_msgs/msg/StateEstimate"
ACK_TYPE = "bench_msgs/msg/StepAck"

SENSOR_MESSAGE_TYPES = {
    "ground_radar": "bench_msgs/msg/RangeAzEl",
    "isl_radio": "bench_msgs/msg/RangeAzEl",
    "relative_position": "bench_msgs/msg/VectorMeasurement",
}


def measurement_topic(sensor: str) -> str:
    return f"/{sensor}/measurement"


def estimate_topic(filter_name: str) -> str:
    return f"/{filter_name}/estimate"


@dataclass
class NodeSpec:
    """One node of the run."""

    name: str
    kind: str  # "truth", "sensor", "filter", "recorder" or "player"
    module: str  # Python module whose ``main()`` / ``NODE_CLASS`` runs it
    publishes: dict[str, str] = field(default_factory=dict)  # topic -> type (data topics only)
    subscribes: dict[str, str] = field(default_factory=dict)
    inputs: list[str] = field(default_factory=list)  # sensors a filter consumes
    check: str = ""
    """"module:function" that builds the node's core objects from (cfg, name) and raises ScenarioError naming
    a bad key. Named, not imported, so that orbit_sim needs no other package of the bench (the launcher
    finds them at run time, as ``ros2 launch`` finds executables)."""


@dataclass
class Graph:
    nodes: list[NodeSpec]

    def node(self, name: str) -> NodeSpec:
        for spec in self.nodes:
            if spec.name == name:
                return spec
        raise KeyError(f"no node '{name}' in this run; nodes: {[n.name for n in self.nodes]}")

    def of_kind(self, kind: str) -> list[NodeSpec]:
        return [n for n in self.nodes if n.kind == kind]

    def expected_subscribers(self, topic: str) -> int:
        return sum(topic in n.subscribes for n in self.nodes)

    def data_topics(self) -> dict[str, str]:
        """Every data topic of the run with its type (what the recorder records)."""
        topics: dict[str, str] = {}
        for spec in self.nodes:
            topics.update(spec.publishes)
        return topics

    def paced_nodes(self) -> list[str]:
        """Nodes whose acknowledgements gate the pacing source (sensors and filters)."""
        return [n.name for n in self.nodes if n.kind in ("sensor", "filter")]


def resolve_filters(cfg: dict, requested: list[str] | None) -> list[str]:
    """The filter node names of the run: ``requested`` or the scenario's ``default_filters``."""
    names = requested or cfg.get("default_filters") or list((cfg.get("filters") or {}).keys())
    if not names:
        raise ScenarioError("no filters requested and the scenario has no 'default_filters'")
    if len(set(names)) != len(names):
        raise ScenarioError(f"filter names must be unique, got {names}")
    for name in names:
        if not name.replace("_", "").isalnum():
            raise ScenarioError(f"filter name '{name}' must be letters, digits and underscores")
    return list(names)


def filter_config(cfg: dict, name: str) -> dict:
    """A filter's settings: ``filter_defaults`` merged with ``filters.NAME`` (type defaults to NAME)."""
    merged = _merge(cfg.get("filter_defaults") or {}, (cfg.get("filters") or {}).get(name) or {})
    merged.setdefault("type", name)
    return merged


def sensor_names(cfg: dict) -> list[str]:
    return list((cfg.get("sensors") or {}).keys())


def build_graph(cfg: dict, filters: list[str], record: bool = True, source: str = "truth") -> Graph:
    """Nodes of a run: the pacing source (``truth`` or a bag ``player``), sensors, filters, recorder."""
    sensors = Section(cfg.get("sensors"), "sensors")
    nodes: list[NodeSpec] = []
    sensor_topics: dict[str, str] = {}
    for sname in sensors.keys():
        stype = sensors.section(sname).get("type", str)
        if stype not in SENSOR_MESSAGE_TYPES:
            raise ScenarioError(f"'sensors.{sname}.type' must be one of {sorted(SENSOR_MESSAGE_TYPES)}, "
                                f"got {stype!r}")
        sensor_topics[sname] = SENSOR_MESSAGE_TYPES[stype]
    if source == "truth":
        nodes.append(NodeSpec("truth", "truth", "orbit_sim.truth_node",
                              publishes={TRUTH_TOPIC: TRUTH_TYPE, CLOCK_TOPIC: CLOCK_TYPE},
                              check="orbit_sim.truth:check_config"))
        for sname, mtype in sensor_topics.items():
            nodes.append(NodeSpec(sname, "sensor", "radar_sensor.sensor_node",
                                  publishes={measurement_topic(sname): mtype},
                                  subscribes={TRUTH_TOPIC: TRUTH_TYPE},
                                  check="radar_sensor.sensor:check_config"))
    elif source == "player":
        pub = {TRUTH_TOPIC: TRUTH_TYPE, CLOCK_TOPIC: CLOCK_TYPE}
        pub.update({measurement_topic(s): t for s, t in sensor_topics.items()})
        nodes.append(NodeSpec("player", "player", "orbit_sim.player_node", publishes=pub))
    else:
        raise ValueError(f"unknown pacing source {source!r}")
    for fname in filters:
        fcfg = filter_config(cfg, fname)
        inputs = fcfg.get("sensors") or list(sensor_topics)
        unknown = [s for s in inputs if s not in sensor_topics]
        if unknown:
            raise ScenarioError(f"'filters.{fname}.sensors' names unknown sensor(s) {unknown}; "
                                f"allowed: {sorted(sensor_topics)}")
        nodes.append(NodeSpec(fname, "filter", "tracker_filters.filter_node",
                              publishes={estimate_topic(fname): ESTIMATE_TYPE},
                              subscribes={measurement_topic(s): sensor_topics[s] for s in inputs},
                              inputs=list(inputs), check="tracker_filters.builders:check_config"))
    if record:
        recorder = NodeSpec("recorder", "recorder", "orbit_sim.recorder_node")
        for spec in list(nodes):
            recorder.subscribes.update(spec.publishes)
        nodes.append(recorder)
    return Graph(nodes)


def _merge(base: dict, extra: dict) -> dict:
    out = dict(base)
    for key, value in extra.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = value
    return out
