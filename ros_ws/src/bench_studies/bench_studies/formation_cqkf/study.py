"""The formation_cqkf study as the report and the sweeps see it (registered in tracking_bench.studies)."""

from pathlib import Path

from bench_eval.study import Study, load_tables
from bench_studies.formation_cqkf import model_error
from bench_studies.formation_cqkf.report import (
    CLAIMS,
    PAPER,
    formation_cqkf_sections,
    paper004_case,
    write_sweep_report,
)

# 2 short runs decide SS's Table 1 values; CW's and CW+bias's and the SS < CW+bias < CW ordering (its
# differences are small against the errors) need more, beyond the demo's budget: the report says how many
# (bench_eval.claims.runs_needed).
STUDY = Study(
    "formation_cqkf",
    PAPER,
    CLAIMS,
    sections=formation_cqkf_sections,
    sweep_report=write_sweep_report,
    sweep_case=paper004_case,
    sweep_extra=model_error.sweep_extra,
    demo_runs=2,
    tables=load_tables(Path(__file__).parent, "formation_cqkf"),
)
