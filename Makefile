# One-command entry points; everything runs inside the virtual environment at .venv.
PYTHON ?= $(shell command -v python3.11 2>/dev/null || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: setup sysdeps run test test-all lint bench clean

setup: sysdeps $(STAMP)

# Headless OpenGL for the camera renderer (EGL on Mesa's llvmpipe) and a C compiler for the model.
sysdeps:
	@if ! ldconfig -p 2>/dev/null | grep -q libEGL_mesa || ! command -v gcc >/dev/null; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    apt-get update -qq && apt-get install -y -qq libegl1 libegl-mesa0 libgl1-mesa-dri gcc; \
	  else \
	    echo "offtrack needs EGL and gcc: sudo apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri gcc"; \
	  fi; \
	fi

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --upgrade pip
	$(BIN)/python -m pip install -e '.[all,dev]'
	touch $(STAMP)

## Set up and run the main job on defaults.
run: setup
	$(BIN)/offtrack run roundabout-test

## Set up, lint and run the default test suite (slow tests excluded), one worker process per core, each test
## file on one worker (its module fixtures built once).
test: setup
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -n auto --dist loadfile --durations=25

## Everything, slow tests included.
test-all: setup
	$(BIN)/python -m pytest -m '' -n auto --dist loadfile

lint: setup
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

## Benchmarks, one JSON object per line.
bench: setup
	$(BIN)/offtrack bench model --json
	$(BIN)/offtrack bench terrain --json
	$(BIN)/offtrack bench render --json
	$(BIN)/offtrack bench vo --json
	$(BIN)/offtrack bench loop --json
	$(BIN)/offtrack bench env --json
	$(BIN)/offtrack bench sweep --json

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache
