# Convenience targets; the README's two commands are scripts/demo.sh and scripts/test.sh
# (a fresh Debian machine may not have make).
.PHONY: setup demo test test-slow test-mpi clean

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

clean:
	rm -rf results .pytest_cache
