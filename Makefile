# Convenience targets; the README's two commands are scripts/demo.sh and scripts/test.sh (docs: scripts/docs.sh)
# (a fresh Debian machine may not have make).
.PHONY: setup demo test test-slow test-mpi test-docs test-all docs clean

setup:
	@bash scripts/setup.sh

demo:
	@bash scripts/demo.sh

test:
	@bash scripts/test.sh -q

test-slow:
	@bash scripts/test.sh -q -m slow

test-mpi:  # one test at a time: each starts mpirun on every core
	@bash scripts/test.sh -q -n 0 -m mpi

test-docs:
	@bash scripts/test.sh -q -m docs

# every tier: the default one, the long validations, MPI, the strict docs build
test-all: test test-slow test-mpi test-docs

docs:
	@bash scripts/docs.sh

clean:
	rm -rf results site .pytest_cache
