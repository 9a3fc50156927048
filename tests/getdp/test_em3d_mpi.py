"""3D deck under ``mpirun -n 2`` (PETSc/MUMPS as a parallel direct solver) equals the serial run (``-m mpi``).

Debian's getdp 3.2.0 is built with PETSc and MUMPS: the argv of a serial ``solve_transient3d`` run,
behind ``mpirun -n 2``, must give the same disk forces (reference: the serial run; round-off only).
Speed is not checked: on the 2 shared vCPUs of the development machine the 2-rank run was slower.
"""
import os
import re
import shutil
import subprocess

import numpy as np
import pytest

from pulseform.solvers.getdp import Conductor, DampedSine, Rect
from pulseform.solvers.getdp.mesh3d import ring_sector_mesh
from pulseform.solvers.getdp.solver3d import MUMPS_PETSC_ARGS_3D, Coil3D, EM3DModel, solve_transient3d

from getdp_testlib import needs_getdp
from test_em3d_static import demo_coil_turns


@pytest.mark.mpi
@pytest.mark.getdp
@needs_getdp
def test_mumps_under_mpirun_equals_serial(work):
    if shutil.which("mpirun") is None:
        pytest.skip("mpirun not found")
    mesh = ring_sector_mesh(work / "disk.msh", demo_coil_turns(), [Rect(0.0, 0.0, 0.06, 0.001)], sector_deg=10.0,
                            h_coil=3e-3, h_conductor=2e-3, h_air=0.02, conductor_layers=2)
    model = EM3DModel(coils=[Coil3D(5, waveform=DampedSine(20e3, 1e4, 1e5))], conductors=[Conductor(3.5e7)],
                      shell=(0.1, 0.125), sector_deg=10.0)
    # MUMPS (the serial default is UMFPACK, which is sequential: MUMPS_PETSC_ARGS_3D under mpirun)
    serial = solve_transient3d(model, mesh, 4e-6, 4, work / "serial", element_output="none",
                               petsc_args=MUMPS_PETSC_ARGS_3D)
    run_dir = work / "mpi"
    (run_dir / "out").mkdir(parents=True)
    old = str(serial.run.run_dir)
    argv = [a.replace(old, str(run_dir)) for a in serial.run.argv]
    shutil.copy(serial.run.run_dir / "run3d.pro", run_dir / "run3d.pro")
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    with open(run_dir / "getdp.log", "w") as log:
        proc = subprocess.run([shutil.which("mpirun"), "-n", "2", *argv], cwd=run_dir, stdout=log,
                              stderr=subprocess.STDOUT, env=env, timeout=600, check=False)
    assert proc.returncode == 0, (run_dir / "getdp.log").read_text()[-3000:]
    f_mpi = np.loadtxt(run_dir / "out" / "cond_F_1.txt", ndmin=2)[:, 1:]
    f_ser = serial.conductor_force[:, 0, :]
    err = np.abs(f_mpi - f_ser).max() / np.abs(f_ser).max()
    print(f"\nmpirun -n 2 vs serial, {mesh.n_tets} tets: conductor force {err:.1e}")
    text = (run_dir / "getdp.log").read_text()
    assert "mumps" in text and re.search(r"\[rank\s+1\]", text)   # MUMPS, and a second rank did run
    assert err < 1e-9
