# Each target sets itself up: a fresh machine needs only python3 and make.
PY      ?= python3
VENV    := .venv
BIN     := $(VENV)/bin
STAMP   := $(VENV)/.installed
DOCS_STAMP := $(VENV)/.installed-docs
WARM    := $(VENV)/warm-up
OUT     ?= demo-out

.PHONY: install browser test test-under-load demo bench docs figures clean

$(BIN)/python:
	$(PY) -m venv $(VENV)

# numba compiles the planner's kernels on their first use (1.5-3 minutes on 2 cores) and
# keeps them in ~/.cache/gcs-planner/kernels/: two plans compile them here, so that a first
# plan after install (the demo's, the whole sample's) and the test processes find them
$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	@echo "compiling the planner's kernels: two plans on the built-in terrain (log: $(WARM).log)"
	$(BIN)/gcs plan gcs/data/demo.toml -o $(WARM) > $(WARM).log 2>&1 || (cat $(WARM).log; false)
	$(BIN)/gcs plan --sample --uavs 4 --k 1 -o $(WARM) >> $(WARM).log 2>&1 || (cat $(WARM).log; false)
	rm -rf $(WARM)
	touch $(STAMP)

install: $(STAMP)

# Debian's Chromium and chromedriver for the live-map browser test (root or sudo installs
# them; otherwise that test reports itself skipped, and CI fails here instead)
browser:
	bash .ci/install-browser.sh

# two test processes per core (-n): most of the wall time of the simulated flights'
# files is waiting on their clocks (tests/conftest.py HANDED_OUT_FIRST hands them out
# beside the files that plan), so with one process per core and one more the 2 cores
# were idle 29 % of a run (pytest 20:46 on 2 cores, nothing else running), with two
# per core 14 % (16:30); a file's tests stay together (their module fixtures)
TEST_ARGS = -q -n $$(( 2 * $$(nproc) )) --dist loadfile --no-loadscope-reorder

test: $(STAMP) browser
	$(BIN)/python -m pytest $(TEST_ARGS)

# the suite beside a CPU hog on every core, three runs in a row (tests/under_load.py)
test-under-load: $(STAMP) browser
	$(BIN)/python tests/under_load.py --runs 3 -- $(TEST_ARGS)

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
