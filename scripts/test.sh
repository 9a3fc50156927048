#!/usr/bin/env bash
# README command 2: install what is missing, then run the default (fast) test tier.
# Extra arguments go to pytest, e.g. `bash scripts/test.sh -m slow` for the long validations.
# Tests run on every core (pytest-xdist, `-n auto`; a test module is the unit a worker takes, so a
# module's shared runs are made once): `bash scripts/test.sh -n 0` runs them in this process, one by one.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$here/scripts/setup.sh"
cd "$here"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
# Python may keep the bytecode it compiles (__pycache__ beside the sources, ignored by git) even where
# PYTHONDONTWRITEBYTECODE is set: the tier starts ~250 Python processes (workers, CLI runs, geometry scripts,
# renderers), each of which would otherwise compile the project's ~1.7 MB of sources again (~0.6 s of CPU each).
unset PYTHONDONTWRITEBYTECODE
# numba's on-disk cache cold (a fresh clone, CI, an edited kernel source): compile the 2D and the 3D kernel families
# once each, in parallel, before the workers start and each compile them at the same time (tests/numba_prewarm.py;
# a warm cache: ~1 s to find out). PULSEFORM_NO_PREWARM=1 skips it.
if [ "${PULSEFORM_NO_PREWARM:-0}" != 1 ]; then
  .venv/bin/python tests/numba_prewarm.py || echo "pulseform: numba prewarm failed; the tests compile what they need" >&2
fi
set +e
.venv/bin/python -m pytest -n auto --dist loadfile "$@"
rc=$?
set -e
if [ "$rc" -eq 5 ]; then
  echo "pulseform: pytest collected no tests: that is a failure" >&2
fi
exit "$rc"
