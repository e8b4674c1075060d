# flexparcel developer targets. Every target creates .venv on first use.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
OUT ?= out

.PHONY: demo test slow bench lint format clean clean-numba-cache

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --upgrade pip
	$(BIN)/pip install -e ".[dev]"
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/flexparcel demo --element-size 25 --out $(OUT)/demo

test: $(STAMP)
	$(BIN)/ruff check src tests examples
	OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 \
	$(BIN)/python -m pytest -q

slow: $(STAMP)
	OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 \
	$(BIN)/python -m pytest -q -m slow

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
