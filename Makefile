# The two commands of the README: `make demo` and `make test`. Both bootstrap .venv from nothing.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: setup test test-fast demo lint bench maps clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[test]'
	touch $(STAMP)

setup: $(STAMP)

lint: setup
	$(BIN)/ruff check solenoid_fmu tests examples benchmarks

test: setup lint
	$(BIN)/python -m pytest -n 2 -q

# Everything but the tests marked slow (over ~20 s each): a quick check while working (~1.5 min on 2 cores).
test-fast: setup lint
	$(BIN)/python -m pytest -n 2 -q -m "not slow"

# The main job: identify B(H) from the demo campaign, maps, eddy parameter, FMUs, validate,
# diagnose, improve; report at build/ps45-demo/report.html, summary.json beside it.
demo: setup
	$(BIN)/solenoid-fmu pipeline fitting/ps45-demo -o build/ps45-demo

# Regenerates the shipped PS45 map (literature steel) with its plots and exports (~1 min).
maps: setup
	$(BIN)/solenoid-fmu maps -o maps/ps45-literature --plot maps/ps45-literature/plots --modelica --mat

bench: setup
	for f in benchmarks/bench_*.py; do $(BIN)/python $$f || exit 1; done

clean:
	rm -rf build .pytest_cache .ruff_cache
