"""The bench's extension points: components registered as Python entry points, looked up by name.

A package adds a node kind, truth model, sensor type, message codec, estimator, dynamics model, initialiser,
metric, offline estimator, bound, study, scenario, scenario section or angle label by naming it in its ``setup.py``
``entry_points`` under one of :data:`GROUPS` (as Stone Soup's ``plugins.py`` loads its components from
package metadata). Nothing generic is edited: the graph, the launcher, the scorer and the report find every
registered component here.

    entry_points={"tracking_bench.sensors": ["ground_radar = radar_sensor.sensor:GROUND_RADAR"]}

Entry points are read from the installed packages' metadata (``pip install -e`` in ``make setup``, or a
colcon install); any ``*.dist-info`` directory on ``sys.path`` counts, which is how the tests register a
throw-away package.
"""

from __future__ import annotations

import importlib
from functools import cache, lru_cache
from importlib.metadata import entry_points

from bench_engine.errors import ScenarioError

GROUPS = {
    "node_kinds": "tracking_bench.node_kinds",  # NodeKind (bench_engine.graph)
    "truth_models": "tracking_bench.truth_models",  # TruthModel (orbit_sim.truth): settings class + builder
    "sensors": "tracking_bench.sensors",  # SensorType
    "codecs": "tracking_bench.codecs",  # message codec (encode item -> msg, decode msg -> item)
    "estimators": "tracking_bench.estimators",  # Filter class
    "dynamics": "tracking_bench.dynamics",  # Builder (settings, cfg) -> DynamicsModel
    "initialisers": "tracking_bench.initialisers",  # Builder (settings, cfg, dynamics) -> Initialiser
    "metrics": "tracking_bench.metrics",  # Metric (bench_eval.scoring)
    "offline": "tracking_bench.offline",  # OfflineEstimator (bench_eval.offline)
    "bounds": "tracking_bench.bounds",  # Bound (bench_eval.bounds)
    "studies": "tracking_bench.studies",  # Study (bench_eval.study)
    "scenarios": "tracking_bench.scenarios",  # path of a scenario YAML file
    "sections": "tracking_bench.sections",  # SectionReader of a top-level key (bench_engine.settings)
    "angle_labels": "tracking_bench.angle_labels",  # a label that is an angle (bench_engine.labels)
}


@lru_cache(maxsize=1)
def _installed_entry_points():
    """Every installed package's entry points, read once per process (one scan of the installed packages'
    metadata instead of one per group)."""
    return entry_points()


@cache
def _entry_points(group: str) -> dict:
    found = {}
    for ep in _installed_entry_points().select(group=GROUPS[group]):
        found.setdefault(ep.name, ep)  # the first on sys.path wins, as for imports
    return found


def names(group: str) -> list[str]:
    """Registered names of a group, sorted."""
    return sorted(_entry_points(group))


@cache
def load(group: str, name: str) -> object:
    """The component registered as ``name`` in ``group``; ScenarioError naming the registered ones if absent."""
    found = _entry_points(group)
    if name not in found:
        raise ScenarioError(
            f"no {group.replace('_', ' ')} named {name!r} is registered; "
            f"registered: {', '.join(sorted(found)) or 'none'} (entry-point group {GROUPS[group]})"
        )
    return found[name].load()


def origin(group: str, name: str) -> str:
    """``module:attribute`` a registered name points at, without loading it (the scorer's cache key names the
    code behind it: bench_eval.offline_cache)."""
    return _entry_points(group)[name].value


def registered(group: str) -> dict[str, object]:
    """Every component of a group, loaded: {name: component}."""
    return {name: load(group, name) for name in names(group)}


@cache
def resolve(reference: str) -> object:
    """The object a ``module:attribute`` string names, imported on first use (a registered component's builder:
    bench_engine.settings.Builder)."""
    module, _, attribute = reference.partition(":")
    return getattr(importlib.import_module(module), attribute)
