# The two set-up commands of the README:
#   make demo   install driftlog and run the default demo scene
#   make test   install everything the tests need (OpenFOAM from Debian included) and run them
PYTHON ?= python3
PIP ?= $(PYTHON) -m pip
PYTEST_ARGS ?=

.PHONY: demo test install install-test report lint

install:
	$(PIP) install -q -e .

demo: install
	driftlog run

install-test:
	sh scripts/install-system-deps.sh
	$(PIP) install -q -e ".[test]"

test: install-test
	$(PYTHON) -m pytest -n 2 $(PYTEST_ARGS)

report: install
	driftlog report

lint:
	ruff check driftlog adapters tests benchmarks
