"""The coupled 3D loop on a coarse sector of the demo (cases/emf_sheet_bulge as a 5 degree sector,
:mod:`...run.coupled3d`): a few EM steps of the staggered loop with the 3D participants.

References: (1) the conservation ledger (Σ nodal forces vs Σ f V of GetDP's element densities) is
exact by construction: round-off; (2) the fixed-mesh 3D EM solve of the same model, mesh and steps
(one getdp process, ``solve_transient3d`` with BDF2): in 2 µs the sheet moves by ~2e-8 m against a
1.5 mm gap, so the coupled run's force history (GetDP's conductor integral and the nodal resultant
the mechanics receives, the latter the trapezoid mean of the step) must equal it to far better than
1e-3; (3) Newton: the impulse the loop books equals Σ m v of the free sheet plus the clamp's share —
checked as the impulse being positive and of the force history's trapezoid.
"""
from pathlib import Path

import numpy as np
import pytest

from pulseform.orchestrator.case.io import load_case
from pulseform.orchestrator.run.coupled3d import SectorOptions, build_sector
from pulseform.orchestrator.coupling.loop import LoopOptions, StaggeredLoop
from pulseform.orchestrator.mech.participants import DolfinxMechanics
from pulseform.solvers.getdp.solver3d import solve_transient3d

REPO = Path(__file__).resolve().parents[2]

COARSE = SectorOptions(sector_deg=5.0, h_sheet=1e-3, sheet_layers=2, h_coil=3e-3)


@pytest.mark.getdp
def test_a_few_coupled_em_steps_of_the_3d_sector(tmp_path):
    case, _ = load_case(REPO / "cases/emf_sheet_bulge/case.toml")
    mesh, model, solver, load = build_sector(case, tmp_path, COARSE)
    mech = DolfinxMechanics(solver)
    n = max(1, round(COARSE.em_step / solver.stable_time_step()))
    loop = StaggeredLoop(load, mech, LoopOptions(n=n, n_min=1, n_max=n))
    rows = []
    loop.run_until(2e-6, on_em_step=rows.append)
    load.close()
    m = len(rows)
    ref = solve_transient3d(model, mesh, 2e-6, m, tmp_path / "fixed", time_scheme="bdf2", element_output="none")
    fz = np.array([r["getdp_force_z_N"] for r in rows])
    held = np.array([r["force_z_N"] for r in rows])
    f_ref = ref.conductor_force[:, 0, 2]
    trap = 0.5 * (np.r_[0.0, f_ref[:-1]] + f_ref)   # the force held over each step: BDF2's trapezoid
    err = np.abs(fz - f_ref).max() / np.abs(f_ref).max()
    err_held = np.abs(held - trap).max() / np.abs(trap).max()
    ledger = max(r["conservation_error_rel"] for r in rows)
    b = solver.bodies["sheet"]
    uz = np.abs(b.x[:, 2] - b.X0[:, 2]).max()
    print(f"\n{mesh.n_tets} EM tets, sheet {len(b.cells)} tets, {m} EM steps of {n} mechanical steps: force vs fixed-mesh "
          f"3D solve {err:.1e}, held force vs its trapezoid {err_held:.1e}, ledger {ledger:.1e}, max u_z {uz:.2e} m, "
          f"impulse (sector) {loop.counters.impulse[2]:.4e} N s")
    assert m >= 4 and np.abs(f_ref).max() > 0
    assert ledger < 1e-12
    assert err < 1e-3 and err_held < 1e-3
    assert abs(loop.counters.impulse[2] - np.sum(trap * np.diff(np.r_[0.0, ref.times]))) < 1e-3 * abs(loop.counters.impulse[2])
