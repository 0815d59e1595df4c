"""The grace_velocity study as the report and the sweeps see it (registered in tracking_bench.studies)."""
from bench_eval.study import Study
from bench_studies.grace_velocity.report import CLAIMS, PAPER, grace_velocity_sections, write_sweep_report

STUDY = Study("grace_velocity", PAPER, CLAIMS, sections=grace_velocity_sections, sweep_report=write_sweep_report)
