"""3D EM stepping, one getdp process per step from a carried state (:mod:`...stepper3d`).

Reference: one getdp process running the same N steps on the same mesh (``solve_transient3d``; for
BDF2 the library's own ``EM_Transient3D_BDF2``, which applies the recurrence on GetDP's vectors in
memory). On a mesh that does not move, N one-step processes must equal it to round-off: the
carried state (the ``.res`` vector, x~ for BDF2, the circuit's Init values) is complete. A disk
with eddy currents under the demo coil driven by the capacitor bank (field, coil and circuit
unknowns all carried).
"""
import numpy as np
import pytest

from pulseform.solvers.getdp import Circuit, Conductor, Rect
from pulseform.solvers.getdp.mesh3d import ring_sector_mesh
from pulseform.solvers.getdp.solver3d import Coil3D, EM3DModel, solve_transient3d
from pulseform.solvers.getdp.stepper3d import EM3DStepper

from getdp_testlib import needs_getdp
from test_em3d_static import demo_coil_turns


@pytest.mark.getdp
@needs_getdp
# BDF2 slow: its per-step processes vs one process (bank, disk) run in the default tier in
# tests/getdp/test_persistent3d.py::test_fixed_mesh_same_as_per_step_and_one_process (1e-12 there)
@pytest.mark.parametrize("scheme", ["euler", pytest.param("bdf2", marks=pytest.mark.slow)])
def test_per_step_processes_equal_one_process(work, scheme):
    mesh = ring_sector_mesh(work / "disk.msh", demo_coil_turns(), [Rect(0.0, 0.0, 0.06, 0.001)], sector_deg=10.0,
                            h_coil=3e-3, h_conductor=2e-3, h_air=0.02, conductor_layers=2)
    model = EM3DModel(coils=[Coil3D(5)], conductors=[Conductor(3.5e7)], circuit=Circuit(50e-6, 6e3, 0.01, 2e-6),
                      shell=(0.1, 0.125), sector_deg=10.0)
    n, t_end = 6, 6e-6
    full = solve_transient3d(model, mesh, t_end, n, work / "full", time_scheme=scheme)
    stepper = EM3DStepper(model, work / "steps", time_scheme=scheme)
    state = stepper.initial_state()
    fz, cur, vc, fd = [], [], [], None
    for k in range(1, n + 1):
        res, state = stepper.step(mesh, state, k * t_end / n)
        fz.append(res.conductor_force[-1, 0, 2])
        cur.append(res.coil_current[-1, 0])
        vc.append(res.capacitor_voltage[-1])
        fd = res.force_density[-1]
    fz, cur, vc = map(np.array, (fz, cur, vc))
    err_f = np.abs(fz - full.conductor_force[:, 0, 2]).max() / np.abs(full.conductor_force[:, 0, 2]).max()
    err_i = np.abs(cur - full.coil_current[:, 0]).max() / np.abs(full.coil_current[:, 0]).max()
    err_v = np.abs(vc - full.capacitor_voltage).max() / 6e3
    err_d = np.abs(fd - full.force_density[-1]).max() / np.abs(full.force_density[-1]).max()
    tm = state.timers
    print(f"\n{scheme}, {mesh.n_tets} tets, {full.n_dofs} dofs: {n} one-step processes vs one {n}-step process: "
          f"F_z {err_f:.1e}, current {err_i:.1e}, capacitor {err_v:.1e}, last force densities {err_d:.1e}; "
          f"per step: process {tm['getdp_process_s'] / n:.3f} s (pre-processing {tm['getdp_pre_s'] / n:.3f} s, "
          f"time loop {tm['getdp_loop_s'] / n:.3f} s), .res io {tm['res_io_s'] / n:.3f} s; "
          f"one process: {full.run.wall_time / n:.3f} s per step")
    assert abs(full.conductor_force[:, 0, 2]).max() > 0
    assert max(err_f, err_i, err_v, err_d) < 1e-9
