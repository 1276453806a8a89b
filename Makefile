# One-command set-up: `make run` (install + the dvc pipeline on the embedded defaults),
# `make test` (install + the test suite).  Everything lives in .venv.  The install compiles no kernel: a command
# compiles the kernels it uses on first use (bench/compile_cost.py; `vibro compile` builds all ahead of time).
PYTHON ?= python3.11
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: install kernels-jit run test test-all bench clean

$(STAMP): pyproject.toml requirements.lock
	@test -x $(BIN)/python || { echo "==> [install 1/3] creating $(VENV) with $(PYTHON)"; $(PYTHON) -m venv $(VENV); }
	@echo "==> [install 2/3] upgrading pip in $(VENV)"
	@$(BIN)/python -m pip install --quiet --upgrade pip
	@echo "==> [install 3/3] installing vibro and its pinned dependencies (requirements.lock) into $(VENV):"
	@echo "    first time about 5 minutes (numpy, numba, scikit-learn, mlflow, dvc, optuna, ...); one line per package"
	@$(BIN)/python -m pip install --progress-bar off -c requirements.lock -e ".[dev]" \
	  | grep --line-buffered -E "^(Collecting|Successfully installed)" | sed -u 's/^/    /' || true
	@$(BIN)/python -c "import pipeline, sim, surrogate, vibrobase" || { echo "install failed: rerun 'make install' to see pip's errors"; exit 1; }
	@touch $(STAMP)
	@echo "==> installed; .venv/bin/vibro --version: $$($(BIN)/vibro --version)"
	@echo "    each model's kernel compiles on first use (numba's cache, once); 'vibro compile' builds them all ahead of time"

install: $(STAMP)

run: install
	@echo "==> running the pipeline: dvc repro under one MLflow parent run (python -m pipeline.tracking.repro)"
	@$(BIN)/python -m pipeline.tracking.repro

# the suite uses every kernel: compiled once each, in parallel, rather than by both test workers at once
kernels-jit: install
	@$(BIN)/vibro compile --jit-only --quiet || echo "    (kernels not precompiled: the tests compile them on first use)"

test: kernels-jit
	$(BIN)/python -m pytest -q -n 2 --dist loadgroup --durations=15

test-all: kernels-jit
	$(BIN)/python -m pytest -q -n 2 --dist loadgroup --durations=25 -m "slow or not slow"

bench: install
	$(BIN)/python -m pip install --quiet heyoka==7.13.2 CyRK==0.20.0 || true   # the bench extra by name: keeps the editable install
	$(BIN)/vibro compile --quiet    # the ahead-of-time kernels the benchmarks time (bench_precision says which it ran)
	$(BIN)/python -m bench.run_all $(BENCH_FLAGS)   # BENCH_FLAGS=--quick for the short version

clean:
	rm -rf $(VENV) .numba_cache .pytest_cache
