# Two commands do all set-up: `make demo` runs every experiment, `make test` runs the tests.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint bench clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(STAMP): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install --quiet -e ".[test,stonesoup]"
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/workbench demo --force

test: $(STAMP)
	$(BIN)/python -m ruff check workbench tests benchmarks
	$(BIN)/python -m pytest -q

lint: $(STAMP)
	$(BIN)/python -m ruff check workbench tests benchmarks

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_sea.py
	$(BIN)/python benchmarks/bench_omni.py
	$(BIN)/python benchmarks/bench_sea_images.py
	$(BIN)/python benchmarks/bench_omni_images.py
	$(BIN)/python benchmarks/bench_terrain.py
	$(BIN)/python benchmarks/bench_sweep.py

clean:
	rm -rf $(VENV) recordings/*.rrd
