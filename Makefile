# railsusp: the two commands a new user needs are `make demo` and `make test`.
# Each creates or refreshes the virtual environment in .venv when pyproject.toml changes.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test lint bench clean browser

# PyTorch's CPU build from TORCH_INDEX where given: on Linux a plain pip install of the
# pinned torch takes the CUDA build of several GB unless pip has the CPU wheel at hand
# (make demo TORCH_INDEX=https://download.pytorch.org/whl/cpu; README, "Two commands")
TORCH_INDEX ?=
# the pin as pyproject.toml states it (one place to change it)
TORCH_PIN := $(shell grep -o "torch==[^\"']*" pyproject.toml)

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(if $(TORCH_INDEX),$(BIN)/python -m pip install --quiet --disable-pip-version-check \
	  '$(TORCH_PIN)' --index-url $(TORCH_INDEX))
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/railsusp demo

lint: $(STAMP)
	$(BIN)/ruff check src tests bench
	$(BIN)/ruff format --check src tests bench

# the report's rendering test (pytest marker "browser") needs Debian's chromium; installed
# here when missing and possible (root, apt), else those tests are skipped
browser:
	@test -x /usr/bin/chromium || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null && \
	  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium \
	   >/dev/null) || echo "chromium not installed: the browser tests will be skipped"; }

# the suite runs in TEST_WORKERS processes (pytest-xdist), one test file per worker so that a
# module's fixture is built once: 2 matches the CI machine's two cores (measured 2026-11-29,
# cold Numba cache: 291 s against 419 s in one process); TEST_WORKERS=0 runs it in one process.
# Each worker's BLAS, OpenMP and Numba pools take its share of the cores (tests/conftest.py)
TEST_WORKERS ?= 2

test: lint browser
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile

bench: $(STAMP)
	$(BIN)/python bench/track.py

clean:
	rm -rf $(VENV) build *.egg-info src/*.egg-info .pytest_cache .ruff_cache
