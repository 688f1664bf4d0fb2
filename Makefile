# The two commands of the README: `make demo` and `make test`. Both bootstrap .venv from nothing.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: setup test demo lint bench maps clean

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

# The main job until the full pipeline (issue 7) lands: one FEM operating point with its field
# plot, then the FMU from the shipped PS45 maps driven by a 10 A/s ramp (fmpy).
DEMO := build/demo
demo: setup
	$(BIN)/solenoid-fmu solve --x-mm 1.5 --i-A 1.5 --plot $(DEMO)/field.png
	$(BIN)/solenoid-fmu maps --from maps/ps45-literature --plot $(DEMO)/maps
	$(BIN)/python examples/ex_fmu_ramp.py maps/ps45-literature $(DEMO)
	$(BIN)/solenoid-fmu export maps/ps45-literature -o $(DEMO)/ps45-native.fmu --backend c

# Regenerates the shipped PS45 map (literature steel) with its plots and exports (~1 min).
maps: setup
	$(BIN)/solenoid-fmu maps -o maps/ps45-literature --plot maps/ps45-literature/plots --modelica --mat

bench: setup
	for f in benchmarks/bench_*.py; do $(BIN)/python $$f || exit 1; done

clean:
	rm -rf build .pytest_cache .ruff_cache
