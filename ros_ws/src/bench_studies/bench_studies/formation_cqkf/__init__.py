"""The ``formation_cqkf`` study: its scenario (scenario.yaml)."""

from pathlib import Path

SCENARIO = Path(__file__).with_name("scenario.yaml")
