# The README's two set-up commands are `make demo` and `make test`; both build the
# virtual environment from pyproject.toml first, so a fresh clone needs nothing else.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
JOBS   ?= 2

.PHONY: venv demo test bench bench-depth clean

venv: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	$(PY) -m plenodecode.demo demo_out

test: $(STAMP)
	$(PY) -m pytest -n $(JOBS) -q

bench: $(STAMP)
	$(PY) -m bench

bench-depth: $(STAMP)
	$(PY) -m bench.depth

clean:
	rm -rf $(VENV) demo_out .pytest_cache
