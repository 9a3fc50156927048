# The README's two commands: `make demo` and `make test`. Both install what is missing first.
PY := .venv/bin/python
DEMO_CASE ?= cases/bar_impact
DEMO_OUT ?= results/demo

.PHONY: setup demo test test-slow test-mpi bench clean

setup:
	@bash scripts/setup.sh

demo: setup
	@.venv/bin/pulseform run $(DEMO_CASE) --out $(DEMO_OUT) --force

test: setup
	@$(PY) -m pytest -q

test-slow: setup
	@$(PY) -m pytest -q -m slow

test-mpi: setup
	@$(PY) -m pytest -q -m mpi

clean:
	rm -rf results .pytest_cache
