"""``pulseform run`` as a child process (sweep members, compare and validation runs).

A child gets SIGTERM when the process that started it dies — it then stops at its next safe point
with a checkpoint (``--resume`` continues it) instead of running on as an orphan.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Mapping, Sequence

from pulseform.solvers.getdp.runner import die_with_parent


def _preexec() -> None:
    import signal

    die_with_parent(signal.SIGTERM)


def run_pulseform(args: Sequence[str], env: Mapping[str, str] | None = None) -> subprocess.CompletedProcess:
    """Run ``pulseform <args>`` (the console script beside this interpreter), output captured as text."""
    exe = str(Path(sys.executable).with_name("pulseform"))
    return subprocess.run([exe, *args], capture_output=True, text=True, env=env, preexec_fn=_preexec)
