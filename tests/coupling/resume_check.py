"""A ``pulseform run`` stopped by SIGINT after its first checkpoint, then resumed: the procedure the
bitwise-resume tests share (the assertions stay in the tests)."""
from __future__ import annotations

import json
import signal
import subprocess
import time
from pathlib import Path

import pytest


def sigint_then_resume(args: list[str], out: Path, delay: float = 0.2
                       ) -> tuple[subprocess.Popen, str, dict, subprocess.CompletedProcess]:
    """Start ``args`` (a ``pulseform run`` into ``out``), send SIGINT ``delay`` s after its first checkpoint, wait,
    then run ``args + ["--resume"]``. Returns (the stopped process, its stderr, the stopped run's metrics,
    the resumed run's completed process); skips the test when the run finished before the signal."""
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 300
    while not (out / "checkpoint.npz").exists() and proc.poll() is None and time.time() < deadline:
        time.sleep(0.005)
    time.sleep(delay)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=300)
    if proc.returncode == 0:
        pytest.skip("the run finished before the signal")
    stopped = json.loads((out / "metrics.json").read_text()) if proc.returncode == 130 else {}
    resumed = subprocess.run(args + ["--resume"], capture_output=True, text=True)
    return proc, err, stopped, resumed
