# navgym developer entry points. `make demo` and `make test` are the README's two commands.
PY ?= python3
VENV ?= .venv
BIN := $(VENV)/bin

.PHONY: setup setup-test demo test lint bench bench-report clean

$(BIN)/python:
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

setup: $(BIN)/python
	$(BIN)/python -m pip install --quiet -e ".[agents,test]"

# the tests also cover the optional `scale` extra (Ray Tune, Optuna, rl-zoo3)
setup-test: setup
	$(BIN)/python -m pip install --quiet -e ".[agents,test,scale]"

demo: setup
	$(BIN)/navgym demo

test: setup-test
	$(BIN)/python -m pytest -q

lint: setup
	$(BIN)/ruff check navgym filters agents benchmarks experiments tests

bench: setup
	$(BIN)/navgym bench filters

# every benchmark at quick settings (a few minutes); rewrites docs/benchmarks.md
bench-report: setup
	$(BIN)/python -m benchmarks.report

clean:
	rm -rf $(VENV) build *.egg-info
