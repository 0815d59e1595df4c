# Two commands: `make demo` and `make test`. Both bootstrap .venv idempotently first. `make docs` builds the
# documentation site into docs/_build/html (warnings are errors; its tutorial's steps are run on shortened runs).
SHELL := /bin/bash
PY := .venv/bin/python
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
export OPENBLAS_NUM_THREADS := 1

.PHONY: setup demo test docs bench clean

setup:
	@bash scripts/setup_env.sh

demo: setup
	$(PY) scripts/demo.py --out runs/demo

test: setup
	$(PY) -m pytest -q -n auto --dist loadfile --no-loadscope-reorder tests

docs: setup
	$(PY) -m sphinx -b html -E -n -W --keep-going -q -j auto docs docs/_build/html
	@echo "docs: docs/_build/html/index.html"

bench: setup
	$(PY) scripts/bench_filters.py
	$(PY) scripts/bench_graph.py

clean:
	rm -rf runs ros_ws/build docs/_build
