# The two commands of the README. Each installs what it needs first (scripts/setup.sh is idempotent).
VENV ?= .venv
PRESET ?= default
OUT ?= runs/demo-$(PRESET)
# TEST_WORKERS=2 runs the suite on two pytest-xdist workers, a test file per worker at a time (module fixtures
# built once; tests/conftest.py gives each worker's torch its share of the cores). 0: one process (the default
# until tests/test_kill.py is shown to hold its timing beside a second worker).
TEST_WORKERS ?= 0
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
