"""The formation_cqkf study as the report and the sweeps see it (registered in tracking_bench.studies)."""
from pathlib import Path

from bench_eval.study import Study, load_tables
from bench_studies.formation_cqkf import model_error
from bench_studies.formation_cqkf.report import (CLAIMS, PAPER, formation_cqkf_sections, paper004_case,
                                                  write_sweep_report)

# 2 runs (about 6 s each) decide SS's Table 1 values; CW's and CW+bias's need ~3-12 and the SS < CW+bias < CW
# ordering tens to thousands (its differences are a few % of the errors): beyond the demo's budget, as the
# report says.
STUDY = Study("formation_cqkf", PAPER, CLAIMS, sections=formation_cqkf_sections, sweep_report=write_sweep_report,
              sweep_case=paper004_case, sweep_extra=model_error.sweep_extra, demo_runs=2,
              tables=load_tables(Path(__file__).parent, "formation_cqkf"))
