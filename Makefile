PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin

.PHONY: demo test lint bench peers clean

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
	$(BIN)/lint-imports

bench: $(BIN)/wavemeter
	$(BIN)/python benchmarks/precision.py

peers: $(BIN)/wavemeter
	$(BIN)/python -m pip install --quiet -e '.[dev,peers]'
	$(BIN)/python -m pip install --quiet --no-deps 'hoqi-bench>=0.1.1' 'minipti>=1.9.3'
	$(BIN)/python benchmarks/peers.py

clean:
	rm -rf $(VENV) wavemeter-demo
