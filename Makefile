PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin

.PHONY: demo test lint bench clean

$(BIN)/wavemeter: pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	@touch $@

demo: $(BIN)/wavemeter
	$(BIN)/wavemeter demo

test: $(BIN)/wavemeter
	$(BIN)/python -m pytest -q

lint: $(BIN)/wavemeter
	$(BIN)/ruff check src tests benchmarks examples
	$(BIN)/ruff format --check src tests benchmarks examples

bench: $(BIN)/wavemeter
	$(BIN)/python benchmarks/precision.py

clean:
	rm -rf $(VENV) wavemeter-demo
