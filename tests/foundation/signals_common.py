"""Helpers of the fault tests (test_signals.py, test_signals_children.py): the coarse corner-fill run, waiting
for a process state, finding child processes, a fake getdp that hangs."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
EXE = str(Path(sys.executable).with_name("pulseform"))
#: the paper's corner fill on very coarse meshes: ~15,000 explicit steps, a few seconds of stepping (its full
#: 320 us: with history rows at ~0.3 ms, 160 us ran ~1.7 s from the first step to the end, shorter than the
#: 1.5 s wait + shutdown of the signal test)
CORNER = [EXE, "run", str(REPO / "cases/corner_fill"), "--quiet", "--set", "bodies.die.mesh_size=4e-3",
          "--set", "bodies.blank.mesh_size=1e-3", "--set", "time.end=3.2e-4", "--set", "output.plots=false"]
TIMERS = ("load_time_s", "mech_time_s", "setup_time_s", "wall_time_s")


def _wait_for(predicate, proc: subprocess.Popen | None = None, timeout: float = 300.0, what: str = "") -> None:
    deadline = time.time() + timeout
    while not predicate():
        if proc is not None and proc.poll() is not None:
            pytest.fail(f"the run ended (exit {proc.returncode}) before {what}")
        if time.time() > deadline:
            pytest.fail(f"timed out waiting for {what}")
        time.sleep(0.005)


def member_dir(out: Path, index: int) -> Path | None:
    """The folder of member ``index`` of the study in ``out`` (named by its case's hash; listed in design.json, which
    the study writes before any member starts), once it exists; else None."""
    import json

    try:
        folder = out / json.loads((out / "design.json").read_text())["members"][index]["folder"]
    except (OSError, ValueError, KeyError, IndexError):
        return None
    return folder if folder.is_dir() else None


def _stepping(out: Path) -> bool:
    log = out / "run.log"
    return log.is_file() and "ExplicitSolver:" in log.read_text(errors="replace")


def _alive(pid: int) -> bool:
    """True while ``pid`` runs (a zombie, dead but not yet reaped by init, counts as ended)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state not in ("Z", "X")


def _children(pid: int, name: str) -> list[int]:
    out = []
    for p in Path("/proc").iterdir():
        if p.name.isdigit():
            try:
                stat = (p / "stat").read_text()
            except OSError:
                continue
            comm, rest = stat[stat.index("(") + 1: stat.rindex(")")], stat[stat.rindex(")") + 2:].split()
            if comm == name and int(rest[1]) == pid:
                out.append(int(p.name))
    return out


def _fake_getdp(folder: Path) -> Path:
    """A getdp that prints one line, records its pid and never returns."""
    folder.mkdir()
    fake = folder / "getdp"
    fake.write_text('#!/bin/sh\necho "Info    : fake getdp hangs"\necho $$ > "$PULSEFORM_TEST_PIDFILE"\n'
                    "exec sleep 1000\n")
    fake.chmod(0o755)
    return folder
