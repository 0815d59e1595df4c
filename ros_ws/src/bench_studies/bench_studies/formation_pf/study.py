"""The formation_pf study as the report sees it (registered in tracking_bench.studies)."""
from pathlib import Path

from bench_eval.study import Study, load_paper
from bench_studies.formation_pf.report import formation_pf_sections

STUDY = Study("formation_pf", *load_paper(Path(__file__).with_name("paper.yaml")), sections=formation_pf_sections)
