"""The tests' ``pulseform`` runs in children forked from one warm process per test worker.

The product's study machinery (:class:`pulseform.orchestrator.run.warm.WarmPool`, used by sweep, converge,
validate and compare) runs ``pulseform.orchestrator.cli.main(argv)`` in a child forked from a process that has
imported the CLI, DOLFINx, the kernels and gmsh once: the same arguments, working folder, standard output and
error and exit code as ``pulseform ARGV`` started as a process of its own (tests/foundation/test_warm.py checks
members bitwise against cold runs), without Python's start-up and the imports (~1 s of CPU per run). The tier
starts ~70 runs and ~50 checks this way instead.

A run that needs a process of its own goes through :func:`subprocess.run` as before: one with its own
environment (``env``), one that is sent signals, reads standard input or checks what a cold process imports.
``PULSEFORM_TEST_COLD=1`` makes every run cold (to compare).
"""

from __future__ import annotations

import atexit
import os
import subprocess
import sys
from pathlib import Path
from typing import Sequence

EXE = str(Path(sys.executable).with_name("pulseform"))
_POOL = None


def _pool():
    """This worker's warm process, started at its first run and closed when the worker ends."""
    global _POOL
    if _POOL is None:
        from pulseform.orchestrator.run.warm import WarmPool

        _POOL = WarmPool()
        atexit.register(_POOL.close)
    return _POOL


def pulseform_cli(argv: Sequence[str], *, cwd: Path | str | None = None, timeout: float = 600,
                  env: dict | None = None) -> subprocess.CompletedProcess:
    """``pulseform ARGV`` in ``cwd``: its exit code and output (text). ``env`` (variables added to this
    environment) or ``PULSEFORM_TEST_COLD=1``: a process of its own; else a child of the warm process."""
    argv = [str(a) for a in argv]
    if env is not None or os.environ.get("PULSEFORM_TEST_COLD") == "1":
        return subprocess.run([EXE, *argv], capture_output=True, text=True, timeout=timeout, cwd=cwd,
                              env=None if env is None else dict(os.environ, **env))
    return _pool().run(argv, cwd=cwd, timeout=timeout)
