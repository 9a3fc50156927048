"""Runs shared by several test modules of this folder (issue 30: the default tier in minutes): the same
`pulseform run` that tests of several modules read (the coarse bar impact of test_run_e2e and test_field_files,
the short demo of test_field_files and test_results_and_loads) runs once per test session. The tests only
read the results folder."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
EXE = str(Path(sys.executable).with_name("pulseform"))


def env_without_display() -> dict:
    """The environment without DISPLAY: the pictures render off-screen."""
    env = dict(os.environ)
    env.pop("DISPLAY", None)
    return env


@pytest.fixture(scope="session")
def shared_run(tmp_path_factory):
    """``shared_run(case, extra, umask=None)``: the results folder of ``pulseform run cases/<case> --out DIR
    --quiet *extra`` (no DISPLAY; under ``umask`` if given), asserted to exit 0. The same arguments give the
    same folder, run once per session (by the first xdist worker that asks: tests/worker_share.py)."""
    from worker_share import once

    def run(case: str, extra: list[str] | tuple[str, ...], umask: int | None = None) -> Path:
        def make(folder: Path) -> dict:
            r = subprocess.run([EXE, "run", str(REPO / "cases" / case), "--out", str(folder / case), "--quiet",
                                *extra], capture_output=True, text=True, env=env_without_display(), timeout=900,
                               preexec_fn=None if umask is None else (lambda: os.umask(umask)))
            assert r.returncode == 0, r.stderr[-3000:]
            return {}

        folder, _ = once(tmp_path_factory, repr(("shared_run", case, tuple(extra), umask)), make)
        return folder / case

    return run
