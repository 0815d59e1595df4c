"""The grace_velocity study as the report and the sweeps see it (registered in tracking_bench.studies)."""

from pathlib import Path

from bench_eval.study import Study, load_tables
from bench_studies.grace_velocity.report import CLAIMS, PAPER, grace_velocity_sections, write_sweep_report

# One run: a run is a day (a large part of the demo's time), so nothing is decided in the demo and the report says
# how many runs would decide each claim (bench_eval.claims.runs_needed).
STUDY = Study(
    "grace_velocity",
    PAPER,
    CLAIMS,
    sections=grace_velocity_sections,
    sweep_report=write_sweep_report,
    demo_runs=1,
    tables=load_tables(Path(__file__).parent, "grace_velocity"),
)
