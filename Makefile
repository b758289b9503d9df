# Two entry points, both idempotent: `make demo` (the main job on the simulated rig) and
# `make test` (the whole test suite). Each makes .venv and installs what it needs from PyPI.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
OUT    ?= out/demo

.PHONY: demo gui test test-fast lint bench clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(BIN)/pip install --quiet -e .
	touch $@

$(VENV)/.installed-dev: pyproject.toml | $(BIN)/python
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $@ $(VENV)/.installed

demo: $(VENV)/.installed
	$(BIN)/gelrig demo --out $(OUT)

$(VENV)/.installed-gui: pyproject.toml | $(BIN)/python
	$(BIN)/pip install --quiet -e '.[gui]'
	touch $@ $(VENV)/.installed

# The window on the built-in simulated compression rig (RIG=path/to/rig.toml for another).
gui: $(VENV)/.installed-gui
	$(BIN)/gelrig gui $(if $(RIG),--rig $(RIG))

test: $(VENV)/.installed-dev
	$(BIN)/python -m pytest -q

test-fast: $(VENV)/.installed-dev
	$(BIN)/python -m pytest -q -m "not slow"

lint: $(VENV)/.installed-dev
	$(BIN)/ruff check .
	$(BIN)/mypy

# every benchmark, each its own process (a failing one is named at the end, the rest still run)
bench: $(VENV)/.installed-dev
	@failed=""; for b in benchmarks/bench_*.py; do echo "== $$b"; \
		$(BIN)/python $$b || failed="$$failed $$b"; done; \
	if [ -n "$$failed" ]; then echo "benchmarks that failed:$$failed"; exit 1; fi

clean:
	rm -rf $(VENV) out build *.egg-info .pytest_cache .mypy_cache .ruff_cache
