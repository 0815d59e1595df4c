"""The star_tracker study as the report and the sweeps see it (registered in tracking_bench.studies)."""
from bench_eval.study import Study
from bench_studies.star_tracker.report import CLAIMS, PAPER, paper_case, star_tracker_sections, write_sweep_report

STUDY = Study("star_tracker", PAPER, CLAIMS, sections=star_tracker_sections, sweep_report=write_sweep_report,
              sweep_case=paper_case)
