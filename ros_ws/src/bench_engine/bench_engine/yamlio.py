"""YAML text parsed and written safely, with libyaml when PyYAML was built with it.

The pure-Python parser took 25 ms for a 20 s leo_radar bag's metadata.yaml and 0.1 s for larger ones, libyaml
about an eighth of that; every bag opened, scored, checked or recovered reads one, and every run reads its
configuration. Both loaders are PyYAML's safe ones: plain data only, and the same ``yaml.YAMLError``s with their
marks on bad text. Writing a run's configuration and its nodes' parameter files took 50 of the 69 ms of a
grace_velocity run plan in the pure-Python emitter; libyaml's writes the same text for them (checked on every
scenario's files), except that it ends a lone scalar without YAML's document end marker (``...``)."""
from __future__ import annotations

from typing import IO, Any

import yaml

LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)


def load(stream: str | bytes | IO) -> Any:
    """The one YAML document in ``stream`` as plain Python data (as ``yaml.safe_load``)."""
    return yaml.load(stream, Loader=LOADER)  # noqa: S506 - a safe loader


def dump(data: Any, **options: Any) -> str:
    """``data`` as YAML text (as ``yaml.safe_dump``, with the same ``options``)."""
    return yaml.dump(data, Dumper=DUMPER, **options)
