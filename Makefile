# Convenience targets; the README's two commands are scripts/demo.sh and scripts/test.sh (docs: scripts/docs.sh)
# (a fresh Debian machine may not have make).
.PHONY: setup demo test test-slow test-mpi docs clean

setup:
	@bash scripts/setup.sh

demo:
	@bash scripts/demo.sh

test:
	@bash scripts/test.sh -q

test-slow:
	@bash scripts/test.sh -q -m slow

test-mpi:
	@bash scripts/test.sh -q -m mpi

docs:
	@bash scripts/docs.sh

clean:
	rm -rf results site .pytest_cache
