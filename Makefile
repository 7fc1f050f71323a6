# Every target bootstraps .venv itself, so a fresh clone needs only `make run` or `make test`.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
export QT_QPA_PLATFORM ?= offscreen

.PHONY: run test test-parts test-typecheck test-wheel-smoke test-docs test-pytest test-firmware lint typecheck docs wheel-smoke bench demo venv resources clean reliability interop-tools firmware-check

# after installing, numba's kernels are compiled into its on-disk cache once (about a minute), so the first run of
# the window or the CLI loads them instead of compiling while the user waits (app/warm_kernels.py)
$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e ".[test,studies,docs]"
	$(BIN)/python -m dualrgb.app.warm_kernels
	touch $(STAMP)

venv: $(STAMP)

run: $(STAMP)
	QT_QPA_PLATFORM= $(BIN)/dualrgb gui --virtual-lab

# pytest-xdist workers for make test (TEST_WORKERS=0: one process). --dist loadscope keeps each module's tests on
# one worker, so a module fixture (a calibration, a study) runs once. More workers than the 2 cores: the run mostly
# waits (the virtual lab's CLI processes wait out lit exposures, fault tests wait on device timeouts), not computes
# (docs/notes/issue-26-suite.md)
TEST_WORKERS ?= 4
TEST_LOGS := build/test-logs

# ruff first: a finding stops CI at once. Then the type check, the wheel smoke and the docs build run BESIDE pytest
# (make -j4): pytest waits most of its time, and their CPU (mypy about 100 s of one core) fits in that. Their output
# goes to build/test-logs/NAME.log: one line when they pass, the whole log when they fail; pytest prints as usual.
# make lets all four finish and fails if any failed.
test: $(STAMP)
	$(BIN)/ruff check .
	$(MAKE) --no-print-directory -j4 test-parts

# what make test runs side by side after ruff (tools/suite_timing.py times this target)
test-parts: test-typecheck test-wheel-smoke test-docs test-pytest test-firmware

# $(call logged,NAME,COMMAND): COMMAND with its output in $(TEST_LOGS)/NAME.log; a line when it passes, the log if not
logged = mkdir -p $(TEST_LOGS); start=$$(date +%s); \
	if $(2) > $(TEST_LOGS)/$(1).log 2>&1; then \
		echo "$(1): passed in $$(($$(date +%s) - start)) s ($(TEST_LOGS)/$(1).log)"; \
	else status=$$?; cat $(TEST_LOGS)/$(1).log; echo "$(1): FAILED, exit $$status ($(TEST_LOGS)/$(1).log)"; \
		exit 1; fi

test-typecheck: $(STAMP)
	@$(call logged,typecheck,$(MAKE) --no-print-directory typecheck)

test-wheel-smoke: $(STAMP)
	@$(call logged,wheel-smoke,$(MAKE) --no-print-directory wheel-smoke)

test-docs: $(STAMP)
	@$(call logged,docs,$(MAKE) --no-print-directory docs)

# the firmware cases run once, in test-firmware
test-pytest: $(STAMP)
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadscope -m "not firmware"

test-firmware: $(STAMP)
	@if $(FIRMWARE_TOOLCHAIN); then $(call logged,firmware,$(MAKE) --no-print-directory firmware-check); \
	else echo "$(FIRMWARE_SKIPPED)"; fi

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/python -m tools.typecheck

typecheck: $(STAMP)
	$(BIN)/python -m tools.typecheck

# the user docs site (docs/, Sphinx + MyST + furo) into build/docs; a warning (a broken link or reference, a page
# left out of every table of contents) fails it
docs: $(STAMP)
	$(BIN)/sphinx-build -W --keep-going -q -b html docs build/docs

# the built wheel in a fresh venv, run from outside the checkout (.ci/wheel_smoke.sh says what it checks)
wheel-smoke: $(STAMP)
	PY=$(PY) .ci/wheel_smoke.sh

# the LED sphere's reference firmware (firmware/README.md): built with avr-gcc, run instruction by instruction on a
# simulated ATmega2560 (simavr) against the sphere protocol suite's firmware cases; their results and the light-off
# times measured at the PWM pins go to build/firmware-check.json. One line where the toolchain is not installed.
FIRMWARE_PACKAGES := gcc-avr avr-libc simavr libsimavr-dev libsimavrparts1
FIRMWARE_TOOLCHAIN := command -v avr-gcc >/dev/null 2>&1 && test -f /usr/include/simavr/sim_avr.h
FIRMWARE_SKIPPED := firmware-check: skipped, the AVR toolchain is not installed (Debian packages $(FIRMWARE_PACKAGES))
FIRMWARE_TESTS := tests/drivers/test_sphere_protocol.py tests/faults/test_sphere_own_safety.py
firmware-check: $(STAMP)
	@if $(FIRMWARE_TOOLCHAIN); then \
		$(MAKE) --no-print-directory -s -C firmware && \
		$(BIN)/python -m pytest -q -p no:cacheprovider -m firmware --firmware-check build/firmware-check.json \
			$(FIRMWARE_TESTS); \
	else echo "$(FIRMWARE_SKIPPED)"; fi

# ArgyllCMS, LittleCMS, ImageMagick, GDAL, exiftool and the AVR toolchain + simavr for the interop and firmware
# tests (apt-get; .ci/run calls it first)
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
