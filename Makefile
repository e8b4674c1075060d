# flexparcel developer targets. Every target creates .venv on first use.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
OUT ?= out

.PHONY: demo test slow bench lint format clean clean-numba-cache browser-test

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --upgrade pip
	$(BIN)/pip install -e ".[dev]"
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/flexparcel demo --element-size 25 --out $(OUT)/demo

# two processes (pytest-xdist), a test file at a time each, so that a module's fixtures are
# built once; each process compiles the numba kernels it needs. A fresh clone on two cores:
# 459 s (one process: about 690 s). --durations prints the slowest tests
test: $(STAMP)
	$(BIN)/ruff check src tests examples
	OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 \
	$(BIN)/python -m pytest -q -n 2 --dist loadfile --durations=15

slow: $(STAMP)
	OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 \
	$(BIN)/python -m pytest -q -m slow

# the viewer (view.html) rendered by headless Chromium; installs chromium (Debian) if missing
browser-test: $(STAMP)
	@command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1 || \
		{ SUDO=$$([ "$$(id -u)" = 0 ] || echo sudo); $$SUDO apt-get update && \
		  $$SUDO apt-get install -y chromium; }
	OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 \
	$(BIN)/python -m pytest -q -rs tests/test_viewer.py

bench: $(STAMP)
	OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 \
	$(BIN)/flexparcel bench --out $(OUT)/bench.json

lint: $(STAMP)
	$(BIN)/ruff check src tests examples
	$(BIN)/ruff format --check src tests examples

format: $(STAMP)
	$(BIN)/ruff format src tests examples
	$(BIN)/ruff check --fix src tests examples

clean:
	rm -rf $(VENV) $(OUT) build *.egg-info src/*.egg-info

# numba's on-disk cache of a kernel does not notice edits to the njit functions it calls in
# other modules (an edit of contact/law.py left faces.py's cached kernels on the old code)
clean-numba-cache:
	find src -name '*.nbi' -delete
	find src -name '*.nbc' -delete
