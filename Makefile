# Two commands do all set-up: `make demo` runs every experiment, `make test` runs the tests.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint bench clean screenshots docs

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(STAMP): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install --quiet -e ".[test,stonesoup,browser,notebook]"
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/workbench demo --force

test: $(STAMP)
	$(BIN)/python -m ruff check workbench tests benchmarks
	$(BIN)/python -m pytest -q -n auto --dist loadfile --no-loadscope-reorder --durations=30

# A PNG per view of the demo's recordings as the web viewer draws them (headless Chromium, Debian's
# chromium and chromium-driver), and the README's picture of each experiment.
screenshots: $(STAMP)
	test -e recordings/sea-paper.rrd || $(BIN)/workbench demo
	$(BIN)/workbench screenshot recordings/*.rrd --out recordings/screenshots --force
	mkdir -p docs/images
	$(BIN)/python -c "import cv2, sys; [cv2.imwrite(f'docs/images/{o}.png', cv2.resize(cv2.imread(f'recordings/screenshots/{i}.default.png'), (1200, 750), interpolation=cv2.INTER_AREA), [cv2.IMWRITE_PNG_COMPRESSION, 9]) for o, i in (('omni', 'omni-paper'), ('sea', 'sea-paper'), ('terrain', 'terrain-common'))]"

# The docs as a site (README, docs/, the tutorials, the API pages from the docstrings) in site/;
# the tests build it with --strict.
docs: $(STAMP)
	$(BIN)/python -m mkdocs build --strict -d site

lint: $(STAMP)
	$(BIN)/python -m ruff check workbench tests benchmarks

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_sea.py
	$(BIN)/python benchmarks/bench_omni.py
	$(BIN)/python benchmarks/bench_isam2.py
	$(BIN)/python benchmarks/bench_sea_images.py
	$(BIN)/python benchmarks/bench_omni_images.py
	$(BIN)/python benchmarks/bench_terrain.py
	$(BIN)/python benchmarks/bench_sweep.py

clean:
	rm -rf $(VENV) recordings/*.rrd
