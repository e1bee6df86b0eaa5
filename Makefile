# One-command entry points; everything runs inside the virtual environment at .venv.
PYTHON ?= $(shell command -v python3.11 2>/dev/null || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: setup run test test-all lint bench clean

setup: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --upgrade pip
	$(BIN)/python -m pip install -e '.[dev]'
	touch $(STAMP)

## Set up and run the main job on defaults.
run: setup
	$(BIN)/offtrack run roundabout-test

## Set up, lint and run the default test suite (slow tests excluded).
test: setup
	$(BIN)/ruff check .
	$(BIN)/python -m pytest

## Everything, slow tests included.
test-all: setup
	$(BIN)/python -m pytest -m ''

lint: setup
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

## Benchmarks, one JSON object per line.
bench: setup
	$(BIN)/offtrack bench model --json

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache
