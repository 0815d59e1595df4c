# Two commands: `make demo` and `make test`. Both bootstrap .venv idempotently first. `make docs` builds the
# documentation site into docs/_build/html (warnings are errors; its tutorial's steps are run on shortened runs).
SHELL := /bin/bash
PY := .venv/bin/python
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
export OPENBLAS_NUM_THREADS := 1

.PHONY: setup demo test test-portable lint format docs bench clean

setup:
	@bash scripts/setup_env.sh

demo: setup
	$(PY) scripts/demo.py --out runs/demo

test: setup
	$(PY) -m pytest -q -n auto --dist loadfile --no-loadscope-reorder tests

# The regression tests' seeded runs on other numerical kernels than this CPU's best, as another machine would run
# them: numpy at its SSE4.2 baseline (no AVX2, no AVX-512 kernels) and OpenBLAS's Sandybridge kernels (AVX without
# FMA), which differ from the defaults of any x86-64 CPU with AVX2 (tests/test_bag_regression.py checks that they
# run and move the last bits; its other tests do not depend on the kernels).
PORTABLE_KERNELS := NPY_DISABLE_CPU_FEATURES="X86_V3 X86_V4 AVX512_ICL AVX512_SPR" OPENBLAS_CORETYPE=Sandybridge

test-portable: setup
	$(PORTABLE_KERNELS) $(PY) -m pytest -q -n auto --dist load tests/test_bag_regression.py -k "seeded_run or kernels"

# The linter and the formatter (ruff.toml) over the whole tree: `make lint` checks (CI), `make format` rewrites.
lint: setup
	.venv/bin/ruff check .
	.venv/bin/ruff format --check .

format: setup
	.venv/bin/ruff check --fix .
	.venv/bin/ruff format .

docs: setup
	$(PY) -m sphinx -b html -E -n -W --keep-going -q -j auto docs docs/_build/html
	@echo "docs: docs/_build/html/index.html"

bench: setup
	$(PY) scripts/bench_filters.py
	$(PY) scripts/bench_graph.py

clean:
	rm -rf runs ros_ws/build docs/_build
