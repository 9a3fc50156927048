"""Failure paths: a clear GetDPError with the log tail; partial outputs stay on disk."""
import os
import stat

import numpy as np
import pytest

from pulseform.solvers.getdp import (Conductor, EMModel, GetDPError, GetDPSolver, run_getdp, slab_mesh,
                                     write_msh22)

from getdp_testlib import needs_getdp


def slab_solver(work, **kw):
    return GetDPSolver(EMModel(False, conductors=[Conductor(3.5e7)], h0_step=1e5), work, **kw)


def test_missing_binary(work):
    solver = slab_solver(work, executable="/nonexistent/getdp")
    with pytest.raises(GetDPError, match="not found") as info:
        solver.step(slab_mesh(1e-3, 1e-4), solver.initial_state(), 1e-6, 1)
    assert info.value.log_path.exists()


@pytest.mark.getdp
@needs_getdp
def test_broken_deck_gives_log_tail(work, tmp_path):
    deck = tmp_path / "broken.pro"
    deck.write_text('Include "%s";\nGroup { Oops = Region[{1}] \n' % (tmp_path / "missing.pro"))
    solver = slab_solver(work, deck=deck)
    with pytest.raises(GetDPError) as info:
        solver.step(slab_mesh(1e-3, 1e-4), solver.initial_state(), 1e-6, 1)
    msg = str(info.value)
    assert "log tail" in msg and "Error" in msg
    assert info.value.returncode != 0
    assert (info.value.run_dir / "mesh.msh").exists()        # what was written stays


def test_killed_process_and_partial_output(work, tmp_path):
    fake = tmp_path / "fake_getdp"
    fake.write_text("#!/bin/sh\necho 'Info    : Theta Time = 1e-06 s (TimeStep 1)'\n"
                    "echo partial > out/W.txt\nkill -9 $$\n")
    fake.chmod(fake.stat().st_mode | stat.S_IEXEC)
    solver = slab_solver(work, executable=str(fake))
    with pytest.raises(GetDPError, match="SIGKILL") as info:
        solver.step(slab_mesh(1e-3, 1e-4), solver.initial_state(), 1e-6, 1, run_name="killed")
    assert "TimeStep 1" in str(info.value)                    # the log tail is in the message
    assert (info.value.run_dir / "out" / "W.txt").read_text() == "partial\n"


def test_log_scan_catches_error_with_zero_return_code(work, tmp_path):
    fake = tmp_path / "fake_getdp"
    fake.write_text("#!/bin/sh\necho 'Error   : something went wrong'\nexit 0\n")
    fake.chmod(fake.stat().st_mode | stat.S_IEXEC)
    mesh = tmp_path / "m.msh"
    write_msh22(slab_mesh(1e-3, 1e-4), mesh)
    with pytest.raises(GetDPError, match="something went wrong"):
        run_getdp(tmp_path / "x.pro", mesh, work, resolution="R", executable=str(fake))


def test_fast_mpi_env_only_in_child(work, tmp_path):
    fake = tmp_path / "fake_getdp"
    fake.write_text("#!/bin/sh\nenv > env.txt\n")
    fake.chmod(fake.stat().st_mode | stat.S_IEXEC)
    mesh = tmp_path / "m.msh"
    write_msh22(slab_mesh(1e-3, 1e-4), mesh)
    info = run_getdp(tmp_path / "x.pro", mesh, work, resolution="R", executable=str(fake))
    env = (info.run_dir / "env.txt").read_text()
    assert "OMPI_MCA_ess_singleton_isolated=1" in env
    assert "OMPI_MCA_ess_singleton_isolated" not in os.environ
    assert info.argv[0] == str(fake) and os.path.isabs(info.argv[1])


def test_scan_log_finds_errors_divergence_and_warnings():
    from pulseform.solvers.getdp.runner import scan_log
    errors, warnings = scan_log("Info    : ok\nWarning : odd value\nKSP did not converge (DIVERGED_ITS)\n"
                                "Error   : out of memory\n")
    assert errors == ["KSP did not converge (DIVERGED_ITS)", "Error   : out of memory"]
    assert warnings == ["Warning : odd value"]
    assert scan_log("Info    : Theta Time = 1e-06 s\nE n d   P r o c e s s i n g\n") == ([], [])


def test_warnings_are_returned(work, tmp_path):
    fake = tmp_path / "fake_getdp"
    fake.write_text("#!/bin/sh\necho 'Warning : something odd'\nexit 0\n")
    fake.chmod(fake.stat().st_mode | stat.S_IEXEC)
    mesh = tmp_path / "m.msh"
    write_msh22(slab_mesh(1e-3, 1e-4), mesh)
    info = run_getdp(tmp_path / "x.pro", mesh, work, resolution="R", executable=str(fake))
    assert info.warnings == ["Warning : something odd"]


def test_bad_inputs_are_rejected(work):
    from pulseform.solvers.getdp import Coil, DampedSine, EMMesh, EMState
    with pytest.raises(ValueError):
        EMModel(True, coils=[Coil(5)])                       # no waveform and no circuit
    solver = slab_solver(work)
    state = solver.initial_state()
    mesh = slab_mesh(1e-3, 1e-4)
    with pytest.raises(ValueError):
        solver.step(mesh, state, 0.0, 1)                    # t_end not after state.t
    with pytest.raises(ValueError):
        solver.step(mesh, state, 1e-6, 0)
    axi = GetDPSolver(EMModel(True, conductors=[Conductor(3.5e7)]), work)
    with pytest.raises(ValueError, match="axis"):
        axi.step(mesh, axi.initial_state(), 1e-6, 1)        # axisymmetric mesh without axis lines
    # a run may not overwrite the folder holding the previous step's .res
    with pytest.raises(ValueError, match="restart data"):
        solver.step(mesh, EMState(t=1e-6, res_path=str(work / "r" / "em.res")), 2e-6, 1, run_name="r")
