# The two commands of the README. Each installs what it needs first (scripts/setup.sh is idempotent).
VENV ?= .venv
PRESET ?= default
OUT ?= runs/demo-$(PRESET)
# The suite runs on TEST_WORKERS pytest-xdist workers (CI's machine has 2 cores), a test file per worker at a
# time (module fixtures built once; tests/conftest.py gives each worker's torch its share of the cores).
# TEST_WORKERS=0: one process. Its cost: docs/architecture.md, "Running the tests".
TEST_WORKERS ?= 2
PYTEST = $(VENV)/bin/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile

.PHONY: setup demo test test-fast
setup:
	@bash scripts/setup.sh

demo: setup
	$(VENV)/bin/pgc demo --preset $(PRESET) --out $(OUT)

test: setup
	$(PYTEST)

test-fast: setup
	$(PYTEST) -m "not slow"
