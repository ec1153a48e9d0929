# Two entry points on a fresh machine (see README):
#   make demo   - create .venv, install hmpc_pin, run examples/track_sine.py
#   make test   - create .venv, install hmpc_pin with the dev and viz extras, run the tests
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python

.PHONY: demo test native lint clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --upgrade pip
	$(PY) -m pip install -e ".[dev,viz]"
	touch $@

# The native kernels (hmpc_pin/native), compiled once per machine and cached (~2 min);
# without a C++ compiler runs take the Python path, and `make test` fails on purpose.
native: $(VENV)/.installed
	$(VENV)/bin/hmpc-pin native --build

demo: $(VENV)/.installed
	-$(VENV)/bin/hmpc-pin native
	$(PY) examples/track_sine.py --out out

test: native
	$(VENV)/bin/ruff check hmpc_pin
	$(VENV)/bin/mypy
	HMPC_PIN_REQUIRE_NATIVE=1 $(PY) -m pytest

lint: $(VENV)/.installed
	$(VENV)/bin/ruff check hmpc_pin tests examples
	$(VENV)/bin/ruff format --check hmpc_pin tests examples

clean:
	rm -rf $(VENV) out
