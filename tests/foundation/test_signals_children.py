"""Faults of pulseform's children and of the machine a user's run must survive (issue 13): a hanging getdp,
SIGKILL with getdp or the gmsh meshing child running, a gmsh meshing call that never returns or crashes, a user
deck's step guards once meshed, a full disk. Each checks real processes and real files, not mocks (split from
test_signals.py: one module per ~30 s, pytest-xdist distributes modules)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import pytest

from signals_common import EXE, REPO, _alive, _children, _fake_getdp, _wait_for


@pytest.mark.parametrize("process, run_folder", [("per_step", "step_00000"), ("persistent", "persistent_001")])
def test_hanging_getdp_stopped_by_the_time_limit(tmp_path, process, run_folder):
    """A getdp that never answers (a fake that sleeps) is stopped after limits.getdp_time_limit_s on
    both EM paths: one line naming the limit and the run folder with its log, exit 1, no child left."""
    env = dict(os.environ, PATH=f"{_fake_getdp(tmp_path / 'bin')}:{os.environ['PATH']}",
               PULSEFORM_TEST_PIDFILE=str(tmp_path / "pid"))
    out = tmp_path / "run"
    t0 = time.time()
    r = subprocess.run([EXE, "run", str(REPO / "cases/emf_sheet_bulge"), "--out", str(out), "--quiet",
                        "--set", "limits.getdp_time_limit_s=2", "--set", f"em.getdp_process={process}"],
                       capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 1
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, r.stderr
    assert "getdp exceeded limits.getdp_time_limit_s = 2 s" in lines[0] and run_folder in lines[0], lines[0]
    assert time.time() - t0 < 60
    assert not _alive(int((tmp_path / "pid").read_text()))
    assert json.loads((out / "metrics.json").read_text())["status"] == "failed"
    assert "fake getdp hangs" in (out / "em" / run_folder / "getdp.log").read_text()


def test_sigkill_of_pulseform_ends_its_getdp(tmp_path):
    """A getdp that would run for 1000 s dies with pulseform (parent-death signal), not 1000 s later."""
    pidfile = tmp_path / "pid"
    env = dict(os.environ, PATH=f"{_fake_getdp(tmp_path / 'bin')}:{os.environ['PATH']}",
               PULSEFORM_TEST_PIDFILE=str(pidfile))
    proc = subprocess.Popen([EXE, "run", str(REPO / "cases/emf_sheet_bulge"), "--out", str(tmp_path / "run"),
                             "--quiet"], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _wait_for(lambda: pidfile.is_file() and pidfile.read_text().strip(), proc, what="getdp to start")
    child = int(pidfile.read_text())
    assert _alive(child)
    proc.kill()
    proc.wait()
    _wait_for(lambda: not _alive(child), timeout=10, what=f"getdp {child} to end after pulseform was killed")


@pytest.mark.slow
@pytest.mark.getdp
def test_sigkill_during_a_real_getdp_step_leaves_no_getdp(tmp_path):
    """Slow tier: the same parent-death signal of the getdp child as test_sigkill_of_pulseform_ends_its_getdp
    (a fake getdp, default tier), here with a real getdp mid-step."""
    proc = subprocess.Popen([EXE, "run", str(REPO / "cases/emf_sheet_bulge"), "--out", str(tmp_path / "run"),
                             "--quiet"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    found: list[int] = []
    _wait_for(lambda: found.extend(_children(proc.pid, "getdp")) or found, proc, what="a getdp child")
    proc.kill()
    proc.wait()
    _wait_for(lambda: not any(_alive(c) for c in found), timeout=10, what="getdp to end")


def test_full_disk_is_one_line_and_keeps_what_was_written(tmp_path):
    """A 400 kB tmpfs fills during the bar-impact run (needs root to mount; skipped elsewhere)."""
    disk = tmp_path / "small"
    disk.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=400k", "tmpfs", str(disk)], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs here: {r.stderr.strip()}")
    try:
        out = disk / "r"
        r = subprocess.run([EXE, "run", str(REPO / "cases/bar_impact"), "--out", str(out), "--quiet"],
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 1
        lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
        assert len(lines) == 1, r.stderr[-3000:]
        assert "no space left to write" in lines[0] and str(out) in lines[0], lines[0]
        import tomllib

        assert tomllib.loads((out / "case.toml").read_text())["case"]["name"] == "bar_impact"  # readable
        assert "ExplicitSolver" in (out / "run.log").read_text(errors="replace")
    finally:
        subprocess.run(["umount", str(disk)], check=False)


@pytest.mark.parametrize("end,limit", [("500", "limits.max_steps = 5e+07"),
                                       pytest.param("0.05", "limits.max_em_steps = 5e+04", marks=pytest.mark.slow)])
def test_user_deck_steps_guarded_once_meshed(tmp_path, end, limit):
    """A user deck's element size is known only after its .geo is meshed: the step guards run then,
    before the first step (at the deck's ~2.3e-8 s stable step, 500 s would be ~2e10 explicit steps,
    50 ms ~2e6 explicit steps but ~1.1e5 getdp runs at coupling.n = 20). The EM-step guard's case (slow tier)
    is the same function after meshing (guards.check_steps_of_meshes, called by the driver); its EM-step
    branch in the default tier: tests/coupling/test_case_3d_sector.py::
    test_too_many_em_steps_are_refused_before_the_first_step."""
    r = subprocess.run([EXE, "run", str(REPO / "cases/user_deck_sheet_bulge"), "--out", str(tmp_path / "r"), "--quiet",
                        "--set", f"time.end={end}"], capture_output=True, text=True, timeout=300)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert "time.end" in lines[0] and f"above {limit}" in lines[0], lines[0]


def test_sigkill_during_built_in_meshing_ends_the_gmsh_child(tmp_path):
    """The gmsh API meshes the built-in geometries in a forked child (solvers/getdp/runner.call_in_child):
    SIGKILL of pulseform while it meshes (a fine sheet mesh, ~3e5 cells, seconds of gmsh) ends it too."""
    proc = subprocess.Popen([EXE, "run", str(REPO / "cases/emf_sheet_bulge"), "--out", str(tmp_path / "run"), "--quiet",
                             "--set", "geometry.mesh_size_sheet=2e-5"], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    found: list[int] = []
    _wait_for(lambda: found.extend(_children(proc.pid, "pulseform")) or found, proc, what="the meshing child")
    proc.kill()
    proc.wait()
    _wait_for(lambda: not any(_alive(c) for c in found), timeout=10, what="the meshing child to end")


#: runs `pulseform` with the gmsh API meshing function replaced by a fake that records its pid and
#: then hangs or aborts (in the forked meshing child: solvers/getdp/runner.call_in_child)
_FAKE_GMSH_DRIVER = '''
import importlib, logging, os, sys, time
logging.getLogger().addHandler(logging.NullHandler())  # as the CLI's console handler: no basicConfig output
mode, module, attr, pidfile = sys.argv[1:5]
def fake(*args, **kwargs):
    with open(pidfile, "w") as fh:
        fh.write(str(os.getpid()))
    if mode == "hang":
        time.sleep(1000)
    os.abort()
setattr(importlib.import_module(module), attr, fake)
from pulseform.orchestrator.cli import main
sys.exit(main(sys.argv[5:]))
'''


_GMSH_MESHING = {
    "body_shape": ("bar_impact", "pulseform.orchestrator.mesh.shapes", "_gmsh_triangles", "meshing body 'left' with gmsh"),
    "em_geometry": ("emf_sheet_bulge", "pulseform.orchestrator.mesh.em_geometry", "coil_conductor_mesh",
                    "meshing the flat_coil_sheet EM geometry with gmsh"),
}


@pytest.mark.parametrize("mode,case,module,attr,what", [
    pytest.param(mode, *args, id=f"{mode}-{name}",
                 marks=[pytest.mark.slow] if (mode, name) == ("hang", "em_geometry") else [])
    for mode in ("hang", "abort") for name, args in _GMSH_MESHING.items()])
def test_gmsh_api_meshing_that_never_returns_or_crashes(tmp_path, case, module, attr, what, mode):
    """A gmsh (API, built-in geometries) that never returns is stopped at limits.gmsh_time_limit_s, one
    that crashes (an abort, as std::bad_alloc does) is a ChildFailed: one line naming the meshing step,
    exit 1, metrics status "failed", and the meshing child does not live on. [hang-em_geometry] is in the slow
    tier: the time limit of the same meshing child (runner.call_in_child) in [hang-body_shape], the EM geometry's
    meshing step and its message in [abort-em_geometry]."""
    driver = tmp_path / "driver.py"
    driver.write_text(_FAKE_GMSH_DRIVER)
    pidfile, out = tmp_path / "pid", tmp_path / "run"
    t0 = time.monotonic()
    r = subprocess.run([sys.executable, str(driver), mode, module, attr, str(pidfile), "run", str(REPO / "cases" / case),
                        "--out", str(out), "--quiet", "--set", "limits.gmsh_time_limit_s=2"],
                       capture_output=True, text=True, timeout=120)
    wall = time.monotonic() - t0
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 1 and len(lines) == 1, r.stderr[-3000:]
    assert lines[0].startswith(f"pulseform: error: {case}: {what} ") and len(lines[0]) <= 300, lines[0]
    if mode == "hang":
        assert "exceeded limits.gmsh_time_limit_s = 2 s and was stopped" in lines[0], lines[0]
        assert 2.0 <= wall < 60, wall
    else:
        assert "died before it finished: killed by signal SIGABRT" in lines[0], lines[0]
    assert json.loads((out / "metrics.json").read_text())["status"] == "failed"
    _wait_for(lambda: not _alive(int(pidfile.read_text())), timeout=10, what="the meshing child to end")
