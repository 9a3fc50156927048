"""3D deck, second-order edge elements (``EM3DModel.order = 2``, the deck's ``Order_a = 2``) vs first order.

Fixed disk (the configuration of ``test_em3d_disk``: the demo's 5-turn coil, Al disk 1 mm x 60 mm, sigma
3.5e7 S/m, 20 kA e^(-1e4 t) sin(1e5 t)) on a deliberately coarse 3D mesh (2.5 degree sector, 2 disk
layers, 1.5 mm in-plane over the coil: 6.1k tetrahedra), 10 implicit Euler steps to 30 us.

Reference: our 2D axisymmetric solver (``GetDPSolver``, nodal r a_phi on triangles, an independent deck)
on the same configuration and steps with 0.25 mm disk elements (its disk-size convergence, from
``test_em3d_disk``: peak F_z 15096 / 15143 N at 0.25 / 0.125 mm, 0.3 %).

Observed here: order 1 peak -8.47 %, impulse -9.46 %, Joule heat +5.83 %; order 2 +0.51 %, +0.43 %,
+0.08 % (4.4k / 26.0k dofs, 0.06 / 0.54 s CPU per step). Checked: order 2 within 1.5 % of the
reference and at least 4 times closer to it than order 1 on each quantity; the per-tetrahedron force
densities (the coupling's input) still add up to the conductor's force with order 2.
"""
import numpy as np
import pytest

from pulseform.solvers.getdp import Coil, Conductor, EMModel, GetDPSolver, coil_conductor_mesh
from pulseform.solvers.getdp.mesh3d import ring_sector_mesh
from pulseform.solvers.getdp.solver3d import Coil3D, EM3DModel, model_numbers, solve_transient3d

from getdp_testlib import needs_getdp
from test_em3d_disk import DISK, SIGMA, WAVE
from test_em3d_static import demo_coil_turns

T_END, N_STEPS, SECTOR = 30e-6, 10, 2.5


def test_order_is_validated():
    with pytest.raises(ValueError, match="order is 1 or 2"):
        EM3DModel(order=3)
    assert EM3DModel().order == 1
    with pytest.raises(ValueError, match="order2_conductors are conductor numbers 1..1"):
        EM3DModel(conductors=[Conductor(SIGMA)], order=2, order2_conductors=(2,))


# slow (order-2 edge elements run in the default tier: closer to Biot-Savart than order 1 on a static field,
# tests/getdp/test_em3d_static.py::test_centre_field_order2_vs_biot_savart[electrokinetic]; with eddy currents and
# the bank in the coupled loop vs a fixed-mesh order-2 solve,
# tests/coupling/test_coupled_racetrack.py::test_order2_em_in_the_coupled_loop_freezes_instead_of_remeshing)
@pytest.mark.slow
@pytest.mark.getdp
@needs_getdp
def test_order2_disk_closer_to_axisymmetric_than_order1(work):
    mesh2 = coil_conductor_mesh([demo_coil_turns()], [DISK], r_domain=0.1, r_shell=0.125, h_fine=1e-3,
                                h_coarse=1e-2, h_conductor=2.5e-4)
    model2 = EMModel(True, coils=[Coil(5, waveform=WAVE)], conductors=[Conductor(SIGMA)], shell=(0.1, 0.125))
    solver = GetDPSolver(model2, work / "axi")
    res2, _ = solver.step(mesh2, solver.initial_state(), T_END, N_STEPS, element_output="none")
    f2, p2 = res2.conductor_force[:, 0, 1], res2.conductor_power[:, 0]
    assert f2.max() > 1e4   # the disk is repelled (+z) with ~15 kN

    mesh = ring_sector_mesh(work / "disk3d.msh", demo_coil_turns(), [DISK], sector_deg=SECTOR, r_air=0.1,
                            r_shell=0.125, h_coil=1.5e-3, h_conductor=2e-3, h_air=0.015, conductor_layers=2,
                            fine_box=((0.0, 0.046, -0.01, 0.01, -0.0005, 0.0015), 1.5e-3))
    errors, dofs = {}, {}
    for order in (1, 2):
        model = EM3DModel(coils=[Coil3D(5, waveform=WAVE)], conductors=[Conductor(SIGMA)], shell=(0.1, 0.125),
                          sector_deg=SECTOR, order=order)
        # order 1 gives the deck exactly the inputs it had before the option (its results are unchanged)
        assert ("Order_a" in model_numbers(model, mesh)[0]) == (order == 2)
        res = solve_transient3d(model, mesh, T_END, N_STEPS, work / f"run{order}", element_output="last")
        np.testing.assert_allclose(res.times, res2.times, rtol=1e-12)
        f3 = res.conductor_force[:, 0, 2] * model.symmetry_factor
        p3 = res.conductor_power[:, 0] * model.symmetry_factor
        errors[order] = np.array([f3.max() / f2.max() - 1, f3.sum() / f2.sum() - 1, p3.sum() / p2.sum() - 1])
        dofs[order] = res.n_dofs
        print(f"\norder {order}: {mesh.n_tets} tets, {res.n_dofs} dofs, {res.cpu_per_step:.3f} s CPU per step: "
              f"peak {errors[order][0]:+.2%}, impulse {errors[order][1]:+.2%}, Joule heat {errors[order][2]:+.2%}")
        # per-tetrahedron force densities add up to the conductor's force (the coupling's input)
        f_el = (res.force_density[-1] * mesh.volumes(res.elements)[:, None]).sum(0)
        np.testing.assert_allclose(f_el, res.conductor_force[-1, 0], rtol=1e-9, atol=1e-9 * f2.max())
        p_el = res.joule_density[-1] @ mesh.volumes(res.elements)
        assert p_el == pytest.approx(res.conductor_power[-1, 0], rel=1e-9)
    assert dofs[2] > 3 * dofs[1]                      # the face and edge functions are there
    assert np.all(np.abs(errors[2]) < 0.015)
    assert np.all(np.abs(errors[2]) < np.abs(errors[1]) / 4)
