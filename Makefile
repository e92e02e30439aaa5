# The two commands of the README. Each installs what it needs first (scripts/setup.sh is idempotent).
VENV ?= .venv
PRESET ?= default
OUT ?= runs/demo-$(PRESET)

.PHONY: setup demo test test-fast
setup:
	@bash scripts/setup.sh

demo: setup
	$(VENV)/bin/pgc demo --preset $(PRESET) --out $(OUT)

test: setup
	$(VENV)/bin/python -m pytest -q

test-fast: setup
	$(VENV)/bin/python -m pytest -q -m "not slow"
