# The two set-up commands of the README:
#   make demo   make a virtual environment (.venv), install driftlog in it, run the demo scene
#   make test   the same with what the tests need (OpenFOAM and ffmpeg from Debian included), and
#               run them
# Everything goes into .venv (scripts/make-venv.sh): it works as root and as a user, and with
# Debian's Python, which refuses system-wide pip installs (externally-managed-environment).
# Afterwards: . .venv/bin/activate  (or call .venv/bin/driftlog directly).
PYTHON ?= python3
VENV ?= .venv
BIN = $(VENV)/bin
PIP = $(BIN)/python -m pip
PYTEST_ARGS ?=

.PHONY: demo test install install-test report lint venv

venv: $(BIN)/python

$(BIN)/python:
	PYTHON=$(PYTHON) sh scripts/make-venv.sh $(VENV)

install: venv
	$(PIP) install -q -e .

demo: install
	$(BIN)/driftlog run

install-test: venv
	sh scripts/install-system-deps.sh
	$(PIP) install -q -e ".[test]"

test: install-test
	$(BIN)/python -m pytest -n 2 $(PYTEST_ARGS)

report: install
	$(BIN)/driftlog report

lint: install-test
	$(BIN)/python -m ruff check driftlog adapters tests benchmarks
