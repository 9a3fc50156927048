"""Helpers of the workflow tests: run the ``pulseform`` console script as users do."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from warm_cli import pulseform_cli

REPO = Path(__file__).resolve().parents[2]
EXE = str(Path(sys.executable).with_name("pulseform"))  # the console script (runs that need a process of their own)


def pulseform(*args: str, timeout: float = 600, env: dict | None = None, cwd=None) -> subprocess.CompletedProcess:
    """``pulseform ARGS`` as users run it (a warm child unless ``env``: tests/warm_cli.py)."""
    return pulseform_cli(args, cwd=cwd, timeout=timeout, env=env)


def one_line_error(r: subprocess.CompletedProcess) -> str:
    """The CLI's error line; fails if the output holds a traceback."""
    assert "Traceback" not in r.stderr, r.stderr[-2000:]
    lines = [ln for ln in r.stderr.splitlines() if ln.startswith("pulseform: error:")]
    assert len(lines) == 1, r.stderr[-2000:]
    return lines[0]
