# navgym developer entry points. `make demo` and `make test` are the README's two commands;
# `.ci/run` runs `make check` (lint, format, type check) and then `make test`.
PY ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
# Packages the type check covers: empty means [tool.mypy] `files` in pyproject.toml.
MYPY_PATHS ?=

.PHONY: setup setup-test demo test docs check lint format typecheck bench bench-report clean

$(BIN)/python:
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

setup: $(BIN)/python
	$(BIN)/python -m pip install --quiet -e ".[agents,test]"

# the tests also cover the optional `scale` extra (Ray Tune, Optuna, rl-zoo3) and the docs site
# (`docs`: mkdocs build --strict)
setup-test: setup
	$(BIN)/python -m pip install --quiet -e ".[agents,test,scale,docs,data]"

demo: setup
	$(BIN)/navgym demo

test: setup-test
	$(BIN)/python -m pytest -q

# the docs site into site/ (mkdocs.yml; `mkdocs serve` to browse it while editing)
docs: setup-test
	$(BIN)/mkdocs build --strict

# lint and format check of the whole tree, and the type check (.ci/run runs `make -k check`
# before the tests, so both report)
check: lint typecheck

# both run; the target fails if either does
lint: setup
	$(BIN)/ruff check .; status=$$?; $(BIN)/ruff format --check . && exit $$status

# rewrites files: ruff's safe fixes and the formatter
format: setup
	$(BIN)/ruff check --fix .
	$(BIN)/ruff format .

typecheck: setup
	$(BIN)/mypy $(MYPY_PATHS)

bench: setup
	$(BIN)/navgym bench filters

# every benchmark at quick settings (a few minutes); rewrites docs/benchmarks.md
bench-report: setup
	$(BIN)/python -m benchmarks.report

clean:
	rm -rf $(VENV) build *.egg-info .mypy_cache .ruff_cache
