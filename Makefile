# Two commands from a fresh machine:  `make demo`  and  `make test`.
# Both create .venv on first use and install the pinned dependencies once; the stamp file
# makes a second run skip the install unless requirements/constraints/setup.py changed.

SHELL := /bin/bash
.SHELLFLAGS := -eo pipefail -c
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
PIP    := $(PY) -m pip install --quiet --disable-pip-version-check
export AMENT_PREFIX_PATH := $(abspath $(VENV))
export ROS_AUTOMATIC_DISCOVERY_RANGE ?= LOCALHOST

.PHONY: demo test venv lint clean

venv: $(STAMP)

$(STAMP): requirements.txt constraints.txt setup.py setup.cfg package.xml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PIP) -r requirements.txt -c constraints.txt 2>&1 | { grep -v '^WARNING: Location' || true; }
	$(PIP) --no-deps --no-build-isolation -e . 2>&1 | { grep -v '^WARNING: Location' || true; }
	touch $(STAMP)

demo: $(STAMP)
	mkdir -p out
	$(PY) -m rearrangement_planner.ros.node_demo --scene default --seed 1 --time-limit 60 --time-scale 10 --record-dir out --plot out/default.png

test: $(STAMP)
	$(PY) -m pytest -q test

lint: $(STAMP)
	$(PIP) ruff==0.17.5 mypy==2.4.1
	$(VENV)/bin/ruff check rearrangement_planner msg_adapters test
	$(VENV)/bin/mypy --config-file setup.cfg

clean:
	rm -rf $(VENV) build *.egg-info
