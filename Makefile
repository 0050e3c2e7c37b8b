# curbside: two entry points, both self-installing (see README.md).
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
export HF_HUB_OFFLINE := 1
export TRANSFORMERS_OFFLINE := 1
export DVC_NO_ANALYTICS := 1
export MPLBACKEND := Agg

.PHONY: install demo test bench clean

$(STAMP): pyproject.toml constraints.txt
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip 2>&1 | grep -v "is ignored" || true
	set -o pipefail; $(PY) -m pip install -q -c constraints.txt torch==2.13.0 2>&1 | grep -v "is ignored"; test $${PIPESTATUS[0]} -eq 0
	set -o pipefail; $(PY) -m pip install -q -c constraints.txt -e ".[dev]" 2>&1 | grep -v "is ignored"; test $${PIPESTATUS[0]} -eq 0
	# Xvfb, where apt can install it, gives the viewer and teleop tests a real X display; without it they use
	# SDL's dummy video driver (the same pygame code, no window server), so a failure here is not an error.
	command -v Xvfb >/dev/null || timeout 180 apt-get install -y -q xvfb >/dev/null 2>&1 \
		|| (timeout 120 apt-get update -q >/dev/null 2>&1 && timeout 180 apt-get install -y -q xvfb >/dev/null 2>&1) \
		|| echo "note: Xvfb not installed; the viewer tests use SDL's dummy video driver"
	touch $(STAMP)

install: $(STAMP)

test: install
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy
	$(PY) -m pytest -n 2 -q

demo: install
	PATH="$(CURDIR)/$(BIN):$$PATH" bash scripts/demo.sh

bench: install
	PATH="$(CURDIR)/$(BIN):$$PATH" bash scripts/bench.sh

clean:
	rm -rf $(VENV) outputs .pytest_cache
