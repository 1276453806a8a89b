# One-command set-up: `make run` (install + the dvc pipeline on the embedded defaults),
# `make test` (install + the test suite).  Everything lives in .venv.
PYTHON ?= python3.11
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: install run test test-all bench clean

$(STAMP): pyproject.toml requirements.lock
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -c requirements.lock -e ".[dev]"
	@touch $(STAMP)

install: $(STAMP)

run: install
	$(BIN)/python -m pipeline.tracking.repro

test: install
	$(BIN)/python -m pytest -q -n 2 --dist loadgroup

test-all: install
	$(BIN)/python -m pytest -q -n 2 --dist loadgroup -m "slow or not slow"

bench: install
	$(BIN)/python -m pip install --quiet heyoka==7.13.2 CyRK==0.20.0 || true   # the bench extra by name: keeps the editable install
	$(BIN)/python -m bench.run_all

clean:
	rm -rf $(VENV) .numba_cache .pytest_cache
