"""The grace_velocity study as the report and the sweeps see it (registered in tracking_bench.studies)."""
from pathlib import Path

from bench_eval.study import Study, load_tables
from bench_studies.grace_velocity.report import CLAIMS, PAPER, grace_velocity_sections, write_sweep_report

# One run: a run is a day (about half the demo's time), so nothing is decided in the demo and the report says
# what would be: 2 runs decide the orderings and Table 1's std, Savitzky-Golay's 0.1 mm/s target needs 3-9.
STUDY = Study("grace_velocity", PAPER, CLAIMS, sections=grace_velocity_sections, sweep_report=write_sweep_report,
              demo_runs=1,
              tables=load_tables(Path(__file__).parent, "grace_velocity"))
