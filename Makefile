# Two entry points on a fresh machine (see README):
#   make demo   - create .venv, install hmpc_pin (no extra), run examples/track_sine.py
#   make test   - create .venv, install hmpc_pin with the dev and viz extras, run the tests
#   make docs   - build the documentation site strictly into docs/_build/html
# Installing builds the compiled core (CMakeLists.txt, about 3 minutes on 2 cores); nothing
# is compiled at run time.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python

.PHONY: demo test docs wheel lint clean

$(VENV)/.installed: pyproject.toml CMakeLists.txt $(wildcard cpp/include/hmpc/*.hpp cpp/src/*.cpp bindings/python/*.cpp bindings/python/*.hpp)
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --upgrade pip
	$(PY) -m pip install -e ".[dev,viz]"
	touch $@

# The demo needs the package and its dependencies only (no extra): a full test environment
# (.installed) serves too, else the package alone is installed.
$(VENV)/.demo: pyproject.toml CMakeLists.txt $(wildcard cpp/include/hmpc/*.hpp cpp/src/*.cpp bindings/python/*.cpp bindings/python/*.hpp)
	if [ ! -f $(VENV)/.installed ] || [ $(VENV)/.installed -ot pyproject.toml ]; then \
	  $(PYTHON) -m venv $(VENV) && $(PY) -m pip install --upgrade pip && \
	  $(PY) -m pip install -e . ; fi
	touch $@

demo: $(VENV)/.demo
	$(PY) examples/track_sine.py --out out

# The suite includes tests/test_wheel.py: `pip wheel .`, the wheel installed into a fresh
# environment with no compiler on PATH, a run from an empty folder.
test: $(VENV)/.installed
	$(VENV)/bin/ruff check hmpc_pin tests examples benchmarks
	$(VENV)/bin/mypy
	HMPC_PIN_REQUIRE_NATIVE=1 $(PY) -m pytest

# The documentation site, strict: warnings are errors (-W, all of them reported with
# --keep-going) and every cross-reference must resolve (-n). Offline: no intersphinx.
docs: $(VENV)/.installed
	$(VENV)/bin/sphinx-build -E -W --keep-going -n -q -b html docs docs/_build/html

# A platform wheel in dist/ (the compiled core inside).
wheel: $(VENV)/.installed
	$(PY) -m pip wheel . --no-deps -w dist

lint: $(VENV)/.installed
	$(VENV)/bin/ruff check hmpc_pin tests examples
	$(VENV)/bin/ruff format --check hmpc_pin tests examples

clean:
	rm -rf $(VENV) out build dist docs/_build docs/api/generated
