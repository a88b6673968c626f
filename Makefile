# The README's two set-up commands are `make demo` and `make test`; both build the
# virtual environment from pyproject.toml first, so a fresh clone needs nothing else.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
JOBS   ?= 2

.PHONY: venv system-deps demo test bench bench-depth clean

venv: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

# Debian's chromium renders the HTML reports in the browser tests (skipped where it cannot be installed).
system-deps:
	@command -v chromium >/dev/null 2>&1 || { \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	    echo "installing Debian chromium for the report tests"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; \
	  else echo "note: chromium not installed and not root; browser tests will be skipped"; fi; }

# The main job on the bundled sample raws (after compiling the numba kernels once, with progress): decode (calibration from calib/), refocus, depth, index page.
demo: $(STAMP)
	$(VENV)/bin/plenodecode warmup
	$(VENV)/bin/plenodecode info sample_raws/illum-mini/scene.lfr
	$(VENV)/bin/plenodecode batch sample_raws -o demo_out \
	    --outputs lightfield,centre,refocus,depth --database calib
	$(VENV)/bin/plenodecode sample_raws/illum-mini/scene.lfr --refocus 1.015 -o demo_out/illum-mini_refocus_alpha1.015.png --overwrite
	$(VENV)/bin/plenodecode refocus demo_out/illum-mini__scene/lightfield.zarr --focal-stack -1:1:9 -o demo_out/focal_stack --overwrite
	@echo
	@echo "Demo outputs are in $(CURDIR)/demo_out/: open demo_out/index.html for the batch index;"
	@echo "light fields (Zarr), centre views, refocused photographs, disparity maps and a focal stack are beside it."

test: $(STAMP) system-deps
	$(PY) -m pytest -n $(JOBS) -q

bench: $(STAMP)
	$(PY) -m bench

bench-depth: $(STAMP)
	$(PY) -m bench.depth

clean:
	rm -rf $(VENV) demo_out .pytest_cache
