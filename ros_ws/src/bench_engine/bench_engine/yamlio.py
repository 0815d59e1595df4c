"""YAML text parsed and written safely, with libyaml when PyYAML was built with it.

libyaml parses several times faster than the pure-Python parser, and every bag opened, scored, checked or
recovered reads a metadata.yaml, every run its configuration. Both loaders are PyYAML's safe ones: plain data
only, and the same ``yaml.YAMLError``s with their marks on bad text. libyaml's emitter, too, is the faster one
for a run's configuration and its nodes' parameter files, and writes the same text for them (checked on every
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
