# Each target sets itself up: a fresh machine needs only python3 and make.
PY      ?= python3
VENV    := .venv
BIN     := $(VENV)/bin
STAMP   := $(VENV)/.installed
DOCS_STAMP := $(VENV)/.installed-docs
OUT     ?= demo-out

.PHONY: install browser test test-under-load demo bench docs figures clean

$(BIN)/python:
	$(PY) -m venv $(VENV)

$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

# Debian's Chromium and chromedriver for the live-map browser test (root or sudo installs
# them; otherwise that test reports itself skipped, and CI fails here instead)
browser:
	bash .ci/install-browser.sh

# one test process per core (-n): most of the suite's wall time is simulated flights
# waiting on the clock, and a file's tests stay together (their module fixtures)
test: $(STAMP) browser
	$(BIN)/python -m pytest -q -n logical --dist loadfile

# the suite beside a CPU hog on every core, three runs in a row (tests/under_load.py)
test-under-load: $(STAMP) browser
	$(BIN)/python tests/under_load.py --runs 3

demo: $(STAMP)
	$(BIN)/gcs demo -o $(OUT)

bench: $(STAMP)
	bash benchmarks/setup_gdal.sh
	$(BIN)/python -m benchmarks

# the documentation site (MkDocs, mkdocs.yml) into site/; --strict: a warning, such as a
# broken link or API reference, is an error
$(DOCS_STAMP): pyproject.toml $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[docs]'
	touch $(DOCS_STAMP)

docs: $(DOCS_STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict

# the pictures README.md and docs/ show, drawn again by the code (docs/figures.py)
figures: $(STAMP)
	$(BIN)/python docs/figures.py

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache
