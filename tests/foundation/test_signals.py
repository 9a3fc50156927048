"""Faults a user's run must survive (issue 13): Ctrl-C / SIGTERM mid-run, a second run on the same folder,
--force on a folder pulseform did not make, a killed sweep, out of memory, a stop while drawing the pictures.
Each checks real processes and real files, not mocks. The faults of the children (getdp, gmsh) and of the
machine (a full disk): test_signals_children.py."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from datetime import datetime

import pytest

from pulseform.orchestrator.cli import main
from signals_common import CORNER, EXE, REPO, TIMERS, _alive, _children, _stepping, _wait_for, member_dir


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory) -> dict:
    """One uninterrupted CORNER run, shared by the resume tests (its metrics: the reference) and
    test_two_runs_on_one_folder (while it steps, three more runs on its folder are started; they must be refused).
    What those three did and how the run ended is recorded here; the tests assert on it."""
    out = tmp_path_factory.mktemp("signals") / "shared"
    first = subprocess.Popen([*CORNER, "--out", str(out)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    _wait_for(lambda: _stepping(out), first, what="the first run's first step")
    second = {}
    for extra in ([], ["--force"], ["--resume"]):
        second[tuple(extra)] = subprocess.run([*CORNER, "--out", str(out), *extra], capture_output=True, text=True)
    _, err = first.communicate(timeout=300)
    return {"out": out, "second": second, "returncode": first.returncode, "stderr": err,
            "metrics": json.loads((out / "metrics.json").read_text()) if (out / "metrics.json").is_file() else None}


@pytest.fixture(scope="module")
def reference(uninterrupted) -> dict:
    assert uninterrupted["returncode"] == 0, uninterrupted["stderr"][-2000:]
    return uninterrupted["metrics"]


@pytest.mark.parametrize("sig", [signal.SIGINT, pytest.param(signal.SIGTERM, marks=pytest.mark.slow)],
                         ids=["SIGINT", "SIGTERM"])
def test_signal_mid_run_then_resume_equals_uninterrupted(sig, reference, tmp_path):
    """SIGTERM (slow tier) takes the same path as SIGINT: one handler for both (SIGTERM stopping a run with a
    checkpoint in the default tier: test_sweep_killed_its_members_stop_with_a_checkpoint and
    test_signal_while_drawing_the_pictures[TERM])."""
    out = tmp_path / "run"
    proc = subprocess.Popen([*CORNER, "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    _wait_for(lambda: _stepping(out), proc, what="the first explicit step")
    time.sleep(1.5)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + sig, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("pulseform: interrupted at t = ") \
        and "continue with --resume" in lines[0], err
    m = json.loads((out / "metrics.json").read_text())
    assert m["status"] == "interrupted" and 0.0 < m["end_time_s"] < 3.2e-4, m
    assert "interrupted at t =" in (out / "run.log").read_text()
    assert (out / "checkpoint.npz").is_file() and (out / "history.csv").is_file()

    r = subprocess.run([*CORNER, "--out", str(out), "--resume"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    got = json.loads((out / "metrics.json").read_text())
    assert got["status"] == "ok"
    for k, v in reference.items():
        if k not in TIMERS:
            assert got[k] == v, k  # bitwise: the checkpoint sits on an EM-step boundary
    # wall time of both segments, not of the resumed one alone: the resumed segment's own wall time from
    # run.log's timestamps (its "case ... ->" line to its "done in" line) plus the first segment's
    assert m["wall_time_s"] > 1.6  # the first segment (set-up + 1.5 s of steps) is above the tolerance below
    stamps = [ln for ln in (out / "run.log").read_text().splitlines() if " case corner_fill -> " in ln or " done in " in ln]
    t = [datetime.strptime(ln[:23], "%Y-%m-%d %H:%M:%S,%f").timestamp() for ln in stamps[-2:]]
    assert got["wall_time_s"] == pytest.approx(m["wall_time_s"] + (t[1] - t[0]), abs=0.8), (m["wall_time_s"], t)


def test_two_runs_on_one_folder(uninterrupted):
    """The first run is the shared uninterrupted run; the three runs started on its folder while it stepped
    (the fixture) were refused."""
    out = uninterrupted["out"]
    assert list(uninterrupted["second"]) == [(), ("--force",), ("--resume",)]
    for extra, r in uninterrupted["second"].items():
        assert r.returncode == 2, (extra, r.stderr)
        assert "in use by a running pulseform" in r.stderr, (extra, r.stderr)
    err = uninterrupted["stderr"]
    assert uninterrupted["returncode"] == 0, err
    m = json.loads((out / "metrics.json").read_text())
    assert m["status"] == "ok" and m["end_time_s"] == pytest.approx(3.2e-4)
    # the lock died with the first run: --force may now replace the folder
    r = subprocess.run([*CORNER, "--out", str(out), "--force", "--set", "time.end=2e-5"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]


def test_force_never_deletes_a_foreign_folder(tmp_path, capsys):
    victim = tmp_path / "VICTIM"
    victim.mkdir()
    (victim / "thesis.tex").write_text("years of work")
    code = main(["run", str(REPO / "cases/bar_impact"), "--out", str(victim), "--force", "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and "not a results folder made by pulseform" in err and str(victim) in err
    assert [p.name for p in victim.iterdir()] == ["thesis.tex"]


def test_sweep_killed_its_members_stop_with_a_checkpoint(tmp_path):
    """SIGKILL of `pulseform sweep`: its warm process dies with it (parent-death signal), the running member,
    forked from that one, gets SIGTERM (parent-death signal), stops at its next step with a checkpoint and status
    "interrupted", and does not live on as an orphan."""
    out = tmp_path / "sweep"
    sweep = subprocess.Popen([EXE, "sweep", *CORNER[2:3], *CORNER[4:], "--param", "time.end=1.6e-4,1.7e-4",
                              "--out", str(out)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    first = lambda: member_dir(out, 0)  # noqa: E731
    _wait_for(lambda: first() is not None and _stepping(first()), sweep, what="the first member's first step")
    member_out = first()
    warm = _children(sweep.pid, "pulseform-warm")
    members = [p for w in warm for p in _children(w, "pulseform")]
    assert len(warm) == 1 and len(members) == 1, (warm, members)
    sweep.kill()
    sweep.wait()
    _wait_for(lambda: not _alive(members[0]), timeout=60, what="the member to stop")
    assert not _alive(warm[0])
    m = json.loads((member_out / "metrics.json").read_text())
    assert m["status"] == "interrupted" and (member_out / "checkpoint.npz").is_file(), m


_OOM_DRIVER = '''
import logging, sys
logging.getLogger().addHandler(logging.NullHandler())  # as the CLI's console handler: no basicConfig output
from pulseform.solvers.dolfinx import output
calls, real = [], output.FieldWriter.write
def write(self, t):
    calls.append(t)
    if len(calls) == 3:  # the third field output: t = 0 and 0.2 ms are on disk
        raise MemoryError()
    return real(self, t)
output.FieldWriter.write = write
from pulseform.orchestrator.cli import main
sys.exit(main(sys.argv[1:]))
'''


def test_out_of_memory_mid_run_is_one_line_and_keeps_the_results(tmp_path):
    """Issue 13, deliverable 3: a MemoryError in the middle of a run (here raised by the third field
    write of a coarse bar impact) ends it with one line naming the time, exit 1, status "failed", and
    what was written before (history, the first two field outputs) stays readable."""
    from pulseform.orchestrator.run.mech_fields import read_fields

    driver = tmp_path / "driver.py"
    driver.write_text(_OOM_DRIVER)
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, str(driver), "run", str(REPO / "cases/bar_impact"), "--out", str(out), "--quiet",
                        "--set", "bodies.left.mesh_size=0.25", "--set", "bodies.right.mesh_size=0.25"],
                       capture_output=True, text=True, timeout=300)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 1 and len(lines) == 1, r.stderr[-3000:]
    assert lines[0].startswith("pulseform: error: bar_impact: out of memory at t = 0.0004 s") and len(lines[0]) <= 300
    assert json.loads((out / "metrics.json").read_text())["status"] == "failed"
    import numpy as np

    h = np.genfromtxt(out / "history.csv", delimiter=",", names=True)
    assert h["time_s"][-1] == pytest.approx(4e-4)
    assert {name: list(f.times) for name, f in read_fields(out).items()} == {"left": [0.0, 2e-4], "right": [0.0, 2e-4]}


_SIGNAL_IN_PICTURES = '''
import os, signal, sys
from pulseform.orchestrator.run import plots
real = plots.plot_energies
def plot_energies(*args, **kw):  # the first picture group after the 3D renderer started
    os.kill(os.getpid(), signal.SIG{sig})
    return real(*args, **kw)
plots.plot_energies = plot_energies
from pulseform.orchestrator.cli import main
sys.exit(main(sys.argv[1:]))
'''


@pytest.mark.parametrize("sig", [pytest.param("INT", marks=pytest.mark.slow), "TERM"])
def test_signal_while_drawing_the_pictures(tmp_path, sig):
    """Issue 13 (audit): a stop signal during the end-of-run pictures ends the drawing at the next
    picture group and kills the 3D renderer: one line saying the run is complete and how to draw the
    pictures, exit 128 + signal, metrics.json complete with status "ok" (was: ignored, exit 0).
    [INT] is in the slow tier: SIGINT and SIGTERM share one handler (run/interrupt.STOP_SIGNALS); [TERM] here,
    SIGINT mid-run in test_signal_mid_run_then_resume_equals_uninterrupted[SIGINT]."""
    driver = tmp_path / "driver.py"
    driver.write_text(_SIGNAL_IN_PICTURES.replace("{sig}", sig))
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, str(driver), "run", str(REPO / "cases/bar_impact"), "--out", str(out), "--quiet",
                        "--set", "bodies.left.mesh_size=0.25", "--set", "bodies.right.mesh_size=0.25"],
                       capture_output=True, text=True, timeout=300)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 128 + getattr(signal, f"SIG{sig}") and len(lines) == 1, r.stderr[-3000:]
    assert lines[0].startswith("pulseform: interrupted while drawing the pictures; the run is complete")
    assert f"'pulseform plot {out}' draws them" in lines[0]
    m = json.loads((out / "metrics.json").read_text())
    assert m["status"] == "ok" and m["status_ok"] == 1.0 and m["end_time_s"] > 0
    assert not (out / "plots" / "deformed_von_mises.png").exists()  # the renderer was stopped
    assert not (out / "plots" / "time_step.png").exists()  # the groups after the signal were skipped
    assert (out / "plots" / "energies.png").is_file()  # the group that was running finished


_AFTER_STOP = """
import os, signal, sys
from pulseform.orchestrator.run import interrupt
leaving = sys.argv[1] == "1"
with interrupt.signals_stop_run(leaving_after_stop=leaving):
    os.kill(os.getpid(), signal.SIGINT)   # the stop: recorded, honoured at the next safe point
    try:
        interrupt.check()
    except interrupt.StopRequested as exc:
        print("stopped", exc.signum, flush=True)
os.kill(os.getpid(), signal.SIGTERM)       # a study's SIGTERM reaching the member on its way out
sys.exit(128 + signal.SIGINT)
"""


@pytest.mark.parametrize("leaving", [True, False], ids=["leaving process", "library use"])
def test_a_sigterm_after_a_stop_does_not_kill_a_leaving_process(leaving):
    """The race of a Ctrl-C to a sweep's process group (test_warm's SIGINT case, lost under load): the member stops at
    a safe point, writes its checkpoint and metrics, and the sweep's SIGTERM reaches it while it leaves. The CLI's run
    (``leaving_after_stop``) exits 130 as a stopped run; a library caller gets its previous SIGTERM handler back."""
    done = subprocess.run([sys.executable, "-c", _AFTER_STOP, "1" if leaving else "0"], capture_output=True, text=True,
                          timeout=120)
    assert done.stdout.strip() == f"stopped {int(signal.SIGINT)}", done.stderr[-2000:]
    assert done.returncode == (128 + signal.SIGINT if leaving else -signal.SIGTERM), done.stderr[-2000:]
