"""The coupled 3D loop (the coarse sector of cases/emf_sheet_bulge_3d, tests/coupling/sector_case.py) on its two EM
paths: one persistent getdp for the run (the default with BDF2,
:class:`~pulseform.solvers.getdp.persistent3d.PersistentEM3DStepper`) and one getdp process per EM
step (``getdp_process="per_step"``, :class:`~pulseform.solvers.getdp.stepper3d.EM3DStepper`).

Reference: the per-step path (an independent carry of the BDF2 state through files). Both run the same
scheme on the same moved meshes and the mechanics receives their forces, so every history column must
agree to round-off (issue 15: "both paths give the same results"; bound 1e-12 relative to each
column's largest magnitude). The persistent path factorises every step here (em.factor_reuse_tol = 0): kept
factors solve each step to a 1e-10 residual, not to round-off (their test: tests/getdp/test_persistent3d.py).
"""
from pathlib import Path

import numpy as np
import pytest

from pulseform.orchestrator.case.io import load_case
from pulseform.orchestrator.coupling.loop import StaggeredLoop
from pulseform.orchestrator.em.participant3d import GetDPLoad3D
from pulseform.orchestrator.mech.participants import DolfinxMechanics
from pulseform.orchestrator.run.participants3d import participants_3d
from pulseform.solvers.getdp.persistent3d import PersistentEM3DStepper
from pulseform.solvers.getdp.stepper3d import EM3DStepper

from .sector_case import CASE, MESH

COLUMNS = ("force_z_N", "getdp_force_z_N", "coil_current_A", "capacitor_voltage_V", "magnetic_energy_J",
           "workpiece_joule_power_W")


def _run(tmp_path: Path, name: str, getdp_process: str):
    case, _ = load_case(CASE, MESH + ["em.factor_reuse_tol=0"])
    solver, _, load, options, _ = participants_3d(case, tmp_path / name)
    if getdp_process != "auto":
        load.close()
        load = GetDPLoad3D(load.mesh, load.model, load.work_dir, load.bodies, load.mover, getdp_process=getdp_process)
    mech = DolfinxMechanics(solver)
    loop = StaggeredLoop(load, mech, options)
    rows = []
    loop.run_until(2e-6, on_em_step=rows.append)
    load.close()
    uz = solver.bodies["sheet"].x[:, 2] - solver.bodies["sheet"].X0[:, 2]
    return load, np.array([[r[c] for c in COLUMNS] for r in rows]), uz


# slow (a second coupled sector run; the same comparison, persistent vs per-step getdp on the same moved meshes
# to 1e-12, runs in the default tier in tests/getdp/test_persistent3d.py::test_moving_mesh_same_as_per_step)
@pytest.mark.slow
@pytest.mark.getdp
def test_persistent_and_per_step_coupled_runs_agree(tmp_path):
    pers_load, pers, uz_p = _run(tmp_path, "persistent", "auto")
    per_load, per, uz = _run(tmp_path, "per_step", "per_step")
    assert isinstance(pers_load.stepper, PersistentEM3DStepper) and isinstance(per_load.stepper, EM3DStepper)
    err = (np.abs(pers - per).max(axis=0) / np.abs(per).max(axis=0)).max()
    err_u = np.abs(uz_p - uz).max() / np.abs(uz).max()
    t_p, t_s = pers_load.timers["getdp_s"], per_load.timers["getdp_s"]
    print(f"\n{len(per)} EM steps: persistent vs per-step, history {err:.1e}, sheet u_z {err_u:.1e}; getdp time "
          f"{t_p:.2f} s vs {t_s:.2f} s ({t_p / t_s:.2f})")
    assert len(per) >= 4 and np.abs(per[:, 0]).max() > 0
    assert err < 1e-12 and err_u < 1e-12
    with pytest.raises(ValueError, match="bdf2"):
        GetDPLoad3D(pers_load.mesh, pers_load.model, tmp_path / "x", pers_load.bodies, pers_load.mover,
                    time_scheme="euler", getdp_process="persistent")
