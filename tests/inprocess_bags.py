"""An in-process run (bench_engine.inprocess) as the scorer's BagData, for the tests: bench_eval.inprocess_runs."""
from bench_eval.inprocess_runs import bag_data, estimates  # noqa: F401  (the tests' import path)
