"""A filter's settings as the scenario states them: ``filter_defaults`` merged with ``filters.NAME``.

Read by the filter node kind (tracker_filters.filter_stage: topics, parameters) and by the filter builders
(tracker_filters.builders), so it sits below both. Registered as the reader of the ``filters`` and
``filter_defaults`` sections.
"""
from __future__ import annotations

from bench_engine.config import ScenarioError, merge


def filter_config(cfg: dict, name: str) -> dict:
    """A filter's settings: ``filter_defaults`` merged with ``filters.NAME`` (type defaults to NAME)."""
    defaults, own = cfg.get("filter_defaults") or {}, (cfg.get("filters") or {}).get(name) or {}
    for key, value in (("filter_defaults", defaults), (f"filters.{name}", own)):
        if not isinstance(value, dict):
            raise ScenarioError(f"'{key}' must be a mapping of settings, got {value!r}")
    merged = merge(defaults, own)
    merged.setdefault("type", name)
    return merged


def read_filters(cfg: dict) -> dict[str, dict]:
    """The ``filters`` section (registered reader of ``filters`` and ``filter_defaults``): each filter's merged
    settings by name. The settings themselves are checked when each filter is built (builders)."""
    filters = cfg.get("filters") or {}
    if not isinstance(filters, dict):
        raise ScenarioError(f"'filters' must be a mapping of filter names to settings, got {filters!r}")
    for name in filters:
        if not str(name).replace("_", "").isalnum():
            raise ScenarioError(f"filter name '{name}' must be letters, digits and underscores")
    return {name: filter_config(cfg, name) for name in filters}
