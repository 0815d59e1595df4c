"""The star_tracker study as the report and the sweeps see it (registered in tracking_bench.studies)."""

from pathlib import Path

from bench_eval.study import Study, load_tables
from bench_studies.star_tracker.report import CLAIMS, PAPER, paper_case, star_tracker_sections, write_sweep_report

# 3 short runs decide every claim; 2 leave the Student t interval too wide for the 30-40 % gain and Table 8's
# JPDAF value (bench_eval.claims.runs_needed).
STUDY = Study(
    "star_tracker",
    PAPER,
    CLAIMS,
    sections=star_tracker_sections,
    sweep_report=write_sweep_report,
    sweep_case=paper_case,
    demo_runs=3,
    tables=load_tables(Path(__file__).parent, "star_tracker"),
)
