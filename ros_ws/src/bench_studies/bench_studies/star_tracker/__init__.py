"""The ``star_tracker`` study (paper 003): its scenario (scenario.yaml)."""

from pathlib import Path

SCENARIO = Path(__file__).with_name("scenario.yaml")
