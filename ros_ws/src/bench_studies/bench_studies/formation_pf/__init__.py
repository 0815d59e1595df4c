"""The ``formation_pf`` study: its scenario (scenario.yaml)."""

from pathlib import Path

SCENARIO = Path(__file__).with_name("scenario.yaml")
