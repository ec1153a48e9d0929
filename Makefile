# Two entry points on a fresh machine (see README):
#   make demo   - create .venv, install hmpc_pin, run examples/track_sine.py
#   make test   - create .venv, install hmpc_pin with the dev and viz extras, run the tests
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python

.PHONY: demo test lint clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --upgrade pip
	$(PY) -m pip install -e ".[dev,viz]"
	touch $@

demo: $(VENV)/.installed
	$(PY) examples/track_sine.py --out out

test: $(VENV)/.installed
	$(VENV)/bin/ruff check hmpc_pin
	$(VENV)/bin/mypy
	$(PY) -m pytest

lint: $(VENV)/.installed
	$(VENV)/bin/ruff check hmpc_pin tests examples
	$(VENV)/bin/ruff format --check hmpc_pin tests examples

clean:
	rm -rf $(VENV) out
