# Every target bootstraps .venv itself, so a fresh clone needs only `make run` or `make test`.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
export QT_QPA_PLATFORM ?= offscreen

.PHONY: run test lint docs wheel-smoke bench demo venv resources clean reliability interop-tools

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e ".[test,studies,docs]"
	touch $(STAMP)

venv: $(STAMP)

run: $(STAMP)
	QT_QPA_PLATFORM= $(BIN)/dualrgb gui --virtual-lab

# lint and type check first: a finding stops CI in seconds, before the slow tests
test: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/python -m tools.typecheck
	$(MAKE) --no-print-directory docs
	$(BIN)/python -m pytest -q
	$(MAKE) --no-print-directory wheel-smoke

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/python -m tools.typecheck

# the user docs site (docs/, Sphinx + MyST + furo) into build/docs; a warning (a broken link or reference, a page
# left out of every table of contents) fails it
docs: $(STAMP)
	$(BIN)/sphinx-build -W --keep-going -q -b html docs build/docs

# the built wheel in a fresh venv, run from outside the checkout (.ci/wheel_smoke.sh says what it checks)
wheel-smoke: $(STAMP)
	PY=$(PY) .ci/wheel_smoke.sh

# ArgyllCMS, LittleCMS, ImageMagick, GDAL and exiftool for the interop tests (apt-get; .ci/run calls it first)
interop-tools:
	.ci/interop-tools.sh

# the fault-injection suite; writes the reliability table of docs/explanation/reliability.md (tests/faults/plugin.py)
reliability: $(STAMP)
	$(BIN)/python -m pytest -q -p no:cacheprovider -m fault --reliability-table docs/explanation/reliability.md

bench: $(STAMP)
	$(BIN)/python -m bench.run

demo: $(STAMP)
	$(BIN)/dualrgb demo --out demo-out

resources: $(STAMP)
	$(BIN)/python -m tools.generate_resources
	$(BIN)/python -m tools.make_presets

clean:
	rm -rf $(VENV) .pytest_cache bench/results build
