# The two commands of the README: `make demo` and `make test`. Both bootstrap .venv from nothing.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: setup setup-system test test-fast demo lint bench maps clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[test]'
	touch $(STAMP)

# Debian packages of the tests: mingw-w64's win64 cross compiler (the FMU's win64 binary), wine64 (runs
# the win64 host test), cmake (builds the FMU's sources/), chromium (renders report.html in the browser
# test; 18 s more). Installed only when missing and when root (as in CI; measured: README); otherwise
# says what is missing and the tests that need them skip naming the package.
SYSTEM_PACKAGES := gcc-mingw-w64-x86-64-win32 wine64 cmake chromium

setup-system:
	@missing=$$(for p in $(SYSTEM_PACKAGES); do dpkg-query -W -f='$${Status}\n' $$p 2>/dev/null \
	    | grep -q 'install ok installed' || echo $$p; done | tr '\n' ' '); \
	if [ -z "$$missing" ]; then echo "setup-system: Debian packages $(SYSTEM_PACKAGES) present"; \
	elif ! command -v apt-get >/dev/null 2>&1; then \
	    echo "setup-system: no apt-get; missing $$missing(tests needing them skip, naming them)"; \
	elif [ "$$(id -u)" != 0 ]; then \
	    echo "setup-system: not root; missing Debian packages $$missing(as root: make setup-system; tests needing them skip, naming them)"; \
	else \
	    echo "setup-system: apt-get install -y --no-install-recommends $$missing"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing \
	        >/dev/null && echo "setup-system: installed $$missing"; \
	fi

setup: setup-system $(STAMP)

lint: setup
	$(BIN)/ruff check solenoid_fmu tests examples benchmarks

# --dist worksteal: a worker that runs dry takes queued tests from the other (the minute-long campaign
# tests otherwise leave one core idle at the end).
# pytest-xdist runs one test per core already: an identification's own FEM workers (solenoid_fmu.identification.
# point_pool) would only add their start-up, so the tests run it in one process (tests/test_point_workers.py
# checks the workers themselves).
test: setup lint
	SOLENOID_FMU_WORKERS=1 $(BIN)/python -m pytest -n 2 --dist worksteal -q

# Everything but the tests marked slow (over ~20 s each): a quick check while working (~5 min on 2 cores, stop 54).
test-fast: setup lint
	SOLENOID_FMU_WORKERS=1 $(BIN)/python -m pytest -n 2 --dist worksteal -q -m "not slow"

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
