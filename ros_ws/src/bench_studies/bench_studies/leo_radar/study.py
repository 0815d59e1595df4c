"""The leo_radar study as the report sees it (registered in tracking_bench.studies)."""
from pathlib import Path

from bench_eval.study import Study, load_paper
from bench_studies.leo_radar.report import leo_sections

STUDY = Study("leo_radar", *load_paper(Path(__file__).with_name("paper.yaml")), sections=leo_sections)
