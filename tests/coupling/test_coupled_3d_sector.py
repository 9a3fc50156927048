"""The coupled 3D loop on a coarse sector of the demo (cases/emf_sheet_bulge_3d as a 5 degree sector on the general
3D geometry-file path, :func:`...run.participants3d.participants_3d`): a few EM steps of the staggered loop with the
3D participants.

References: (1) the conservation ledger (Σ nodal forces vs Σ f V of GetDP's element densities) is
exact by construction: round-off; (2) the fixed-mesh 3D EM solve of the same model, mesh and steps
(one getdp process, ``solve_transient3d`` with BDF2): in 2 µs the sheet moves by ~2e-8 m against a
1.5 mm gap, so the coupled run's force history (GetDP's conductor integral and the nodal resultant
the mechanics receives, the latter the trapezoid mean of the step) must equal it to far better than
1e-3; (3) Newton: the impulse the loop books equals Σ m v of the free sheet plus the clamp's share —
checked as the impulse being positive and of the force history's trapezoid.
"""
from pathlib import Path

import json
import subprocess
import sys

import numpy as np
import pytest

from pulseform.orchestrator.case.io import load_case
from pulseform.orchestrator.coupling.loop import StaggeredLoop
from pulseform.orchestrator.mech.participants import DolfinxMechanics
from pulseform.orchestrator.run.participants3d import participants_3d
from pulseform.solvers.getdp.solver3d import solve_transient3d

from .sector_case import CASE, MESH, REPO


@pytest.mark.getdp
def test_a_few_coupled_em_steps_of_the_3d_sector(tmp_path):
    case, _ = load_case(CASE, MESH)
    solver, _, load, options, _ = participants_3d(case, tmp_path)
    mesh, model, n = load.mesh, load.model, options.n
    mech = DolfinxMechanics(solver)
    loop = StaggeredLoop(load, mech, options)
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


@pytest.mark.slow
@pytest.mark.getdp
def test_3d_sector_of_the_demo_vs_the_axisymmetric_run(tmp_path):
    """Issue 20 case (a): the demo as a coupled 1.25 degree sector (`pulseform run cases/emf_sheet_bulge_3d`, 60 µs,
    ~6-7 min on 2 shared cores) against `pulseform run cases/emf_sheet_bulge` on the 0.25 mm mesh (the
    axisymmetric reference: cases/emf_sheet_bulge/reference/convergence.md finds it within 0.7 % of converged; the
    shipped 0.5 mm mesh is 6.9 % low in deflection itself). The issue's bars: max deflection 3 % (the sheet's
    largest |u_z|), impulse 2 % (the sector's axial impulse times 360 / 1.25), ledger at round-off."""
    exe = str(Path(sys.executable).with_name("pulseform"))
    subprocess.run([exe, "run", str(CASE), "--out", str(tmp_path / "sector"), "--quiet", "--set", "output.plots=false"],
                   check=True)
    m3 = json.loads((tmp_path / "sector" / "metrics.json").read_text())
    subprocess.run([exe, "run", str(REPO / "cases/emf_sheet_bulge"), "--out", str(tmp_path / "axi"), "--quiet",
                    "--set", "output.plots=false", "--set", "geometry.mesh_size_sheet=0.25e-3",
                    "--set", "geometry.mesh_size_coil=0.5e-3", "--set", "geometry.mesh_size_air=0.01"], check=True)
    m2 = json.loads((tmp_path / "axi" / "metrics.json").read_text())
    d = m3["sheet_max_uz_mm"] / m2["max_deflection_mm"] - 1
    i = m3["force_impulse_z_Ns"] / m2["force_impulse_z_Ns"] - 1
    print(f"\n3D sector ({m3['em_tets']:.0f} EM tets, {m3['sheet_tets']:.0f} sheet tets, {m3['em_steps']:.0f} EM / "
          f"{m3['mech_steps']:.0f} mechanical steps, {m3['wall_time_s']:.0f} s) vs axisymmetric 0.25 mm: deflection "
          f"{m3['sheet_max_uz_mm']:.4f} vs {m2['max_deflection_mm']:.4f} mm ({d:+.2%}), impulse "
          f"{m3['force_impulse_z_Ns']:.5f} vs {m2['force_impulse_z_Ns']:.5f} N s ({i:+.2%}), ledger "
          f"{m3['conservation_error_rel']:.1e}")
    assert abs(d) < 0.03 and abs(i) < 0.02
    assert m3["conservation_error_rel"] < 1e-12
