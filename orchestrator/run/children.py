"""``pulseform run`` as a child process of its own (a study's members when no warm process serves them:
:mod:`.warm`; ``sweep --mpi``'s workers).

A child gets SIGTERM when the process that started it dies — it then stops at its next safe point
with a checkpoint (``--resume`` continues it) instead of running on as an orphan.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import Mapping, Sequence

from pulseform.solvers.getdp.runner import die_with_parent


def _preexec() -> None:
    import signal

    die_with_parent(signal.SIGTERM)


def member_env() -> dict[str, str]:
    """The environment of a child ``pulseform``: this one without the Open MPI job variables (under
    ``mpirun``, a child would otherwise try to join the parent's MPI job instead of running as its own
    singleton)."""
    return {k: v for k, v in os.environ.items()
            if not (k.startswith(("OMPI_", "PMIX_", "PMI_")) and k not in _KEEP_OMPI)}


_KEEP_OMPI = ("OMPI_ALLOW_RUN_AS_ROOT", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM")


def run_pulseform(args: Sequence[str], env: Mapping[str, str] | None = None, cwd: Path | str | None = None,
                  timeout: float | None = None) -> subprocess.CompletedProcess:
    """Run ``pulseform <args>`` (the console script beside this interpreter) in ``cwd`` (default: this
    process's working folder), output captured as text; ``timeout`` (s): killed after it
    (:class:`subprocess.TimeoutExpired`)."""
    exe = str(Path(sys.executable).with_name("pulseform"))
    return subprocess.run([exe, *args], capture_output=True, text=True, env=env, cwd=cwd, timeout=timeout,
                          preexec_fn=_preexec)


def failure_report(r: subprocess.CompletedProcess, out: Path, lines: int = 12) -> tuple[str, str]:
    """(one line, the log tail) of a member that failed: its ``pulseform: error`` line (else its last line of
    standard error, else its exit code or signal) and the rest of its standard error, else the end of its
    ``run.log``."""
    err = [ln for ln in (r.stderr or "").splitlines() if ln.strip()]
    first = next((i for i, ln in enumerate(err) if ln.startswith("pulseform: ")), None)
    if first is not None:
        error = err[first]
        rest = err[first + 1:]
    elif err:
        error, rest = err[-1], err[:-1]
    elif r.returncode < 0:
        error, rest = f"killed by {signal.Signals(-r.returncode).name}", []
    else:
        error, rest = f"exit code {r.returncode}", []
    if not rest and (out / "run.log").is_file():
        rest = [ln for ln in (out / "run.log").read_text(errors="replace").splitlines() if ln.strip()]
    return error, "\n".join(rest[-lines:])
