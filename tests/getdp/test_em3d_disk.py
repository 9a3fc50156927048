"""3D deck: a fixed disk under the demo's coil vs the axisymmetric solver (slow tier).

Configuration of ``cases/emf_fixed_disk``: 5-turn coil (turns 4 mm x 3 mm, inner radius 12 mm, 2 mm
apart, top 1 mm under the disk), Al disk 1 mm thick, radius 60 mm, sigma 3.5e7 S/m (skin depth at
1e5 rad/s: 0.67 mm), prescribed current 20 kA e^(-1e4 t) sin(1e5 t), 0 to 30 us in 30 steps of
implicit Euler, or of BDF2 (the demo's scheme; the 2D solver's BDF2 runs one getdp process per step),
air sphere 100 mm with a shell to 125 mm in both models.

Reference: our 2D axisymmetric solver (``GetDPSolver``, Lib_PulsedForming.pro, nodal r a_phi on
triangles: an independent discretisation and deck) run here on the same configuration and time
steps with disk elements of 0.125 mm (its disk-size convergence at these steps: peak F_z 14725,
15096, 15143 N at 0.5, 0.25, 0.125 mm). The 3D run: a 1.25 degree sector with its meridian planes
as n x a = 0 symmetry planes; the disk is extruded in 8 layers (0.125 mm) from triangles of
0.35 mm over the coil (r < 46 mm), coarser beyond; the full device's axial force is 288 x the
sector's. Checked: peak F_z and impulse (sum of F_z dt over the 30 steps) within 2 % (the issue's bar), and
the disk's Joule heat (sum of P dt) with the same bar.

Observed while choosing the mesh (same steps; peak / impulse vs this reference; sector, disk layers,
in-plane size over the coil, tetrahedra): 10 deg, free tets 0.5 mm, 47.7k: -3.8 % / -5.2 %;
10 deg, 4 layers, 1 mm, 22.4k: -5.6 % / -7.7 %; 10 deg, 4, 0.5 mm, 69.1k: -1.7 % / -2.6 %;
5 deg, 8, 0.5 mm, 43.2k: -1.1 % / -1.8 %; 2.5 deg, 8, 0.5 mm, 25.8k: -1.0 % / -1.6 %;
2.5 deg, 8, 0.35 mm, 46.0k: -0.55 % / -0.89 %; 1.25 deg, 8, 0.35 mm, 30.3k: -0.48 % / -0.79 %;
1.25 deg, 8, 0.25 mm, 51.0k: -0.30 % / -0.47 % -- first-order convergence towards the 2D result.
"""
import numpy as np
import pytest

from pulseform.solvers.getdp import Coil, Conductor, DampedSine, EMModel, GetDPSolver, Rect, coil_conductor_mesh
from pulseform.solvers.getdp.mesh3d import ring_sector_mesh
from pulseform.solvers.getdp.solver3d import Coil3D, EM3DModel, solve_transient3d

from getdp_testlib import needs_getdp
from test_em3d_static import demo_coil_turns

T_END, N_STEPS = 30e-6, 30
WAVE = DampedSine(20e3, 1e4, 1e5)
DISK = Rect(0.0, 0.0, 0.06, 0.001)
SIGMA = 3.5e7


def axisymmetric_force(work, scheme: str):
    mesh = coil_conductor_mesh([demo_coil_turns()], [DISK], r_domain=0.1, r_shell=0.125, h_fine=1e-3,
                               h_coarse=1e-2, h_conductor=1.25e-4)
    model = EMModel(True, coils=[Coil(5, waveform=WAVE)], conductors=[Conductor(SIGMA)], shell=(0.1, 0.125))
    solver = GetDPSolver(model, work / f"axi_{scheme}", time_scheme=scheme)
    state = solver.initial_state()
    if scheme == "euler":
        res, _ = solver.step(mesh, state, T_END, N_STEPS, element_output="none")
        return res.times, res.conductor_force[:, 0, 1], mesh.n_nodes, res.conductor_power[:, 0]
    t, f, p = [], [], []
    for k in range(1, N_STEPS + 1):   # the 2D BDF2: one getdp run per step
        res, state = solver.step(mesh, state, k * T_END / N_STEPS, 1, element_output="none")
        t.append(res.times[-1])
        f.append(res.conductor_force[-1, 0, 1])
        p.append(res.conductor_power[-1, 0])
    return np.array(t), np.array(f), mesh.n_nodes, np.array(p)


@pytest.mark.slow
@pytest.mark.getdp
@needs_getdp
@pytest.mark.parametrize("scheme", ["euler", "bdf2"])
def test_fixed_disk_force_history_vs_axisymmetric(work, scheme):
    t2, f2, nodes2, p2 = axisymmetric_force(work, scheme)
    sector = 1.25
    mesh = ring_sector_mesh(work / "disk3d.msh", demo_coil_turns(), [DISK], sector_deg=sector, r_air=0.1,
                            r_shell=0.125, h_coil=1.5e-3, h_conductor=1.5e-3, h_air=0.015, conductor_layers=8,
                            fine_box=((0.0, 0.046, -0.01, 0.01, -0.0005, 0.0015), 0.35e-3))
    model = EM3DModel(coils=[Coil3D(5, waveform=WAVE)], conductors=[Conductor(SIGMA)], shell=(0.1, 0.125),
                      sector_deg=sector)
    res = solve_transient3d(model, mesh, T_END, N_STEPS, work / "run3d", element_output="last", time_scheme=scheme)
    f3 = res.conductor_force[:, 0, 2] * model.symmetry_factor
    np.testing.assert_allclose(res.times, t2, rtol=1e-12)
    dt = T_END / N_STEPS
    peak_err = f3.max() / f2.max() - 1
    imp_err = f3.sum() / f2.sum() - 1
    hist = np.abs(f3 - f2).max() / f2.max()
    print(f"\n{scheme}: 2D ({nodes2} nodes): peak {f2.max():.1f} N at {t2[f2.argmax()] * 1e6:.1f} us, impulse {f2.sum() * dt:.5f} N s"
          f"\n3D ({mesh.n_tets} tets, {res.n_dofs} dofs, {res.wall_per_step:.2f} s per step): peak {f3.max():.1f} N "
          f"at {res.times[f3.argmax()] * 1e6:.1f} us, impulse {f3.sum() * dt:.5f} N s"
          f"\npeak {peak_err:+.2%}, impulse {imp_err:+.2%}, max |F3D - F2D| / peak {hist:.2%}")
    k = f3.argmax()
    third = abs(f3[k] + res.coil_force[k, 0, 2] * model.symmetry_factor) / f3[k]
    print(f"|F_disk + F_coil| / F_disk at the peak: {third:.2e} (Newton's third law, not asserted)")
    assert f2.max() > 1e4                       # the disk is repelled (+z) with ~15 kN
    assert abs(peak_err) < 0.02
    assert abs(imp_err) < 0.02
    # Joule heat of the disk (sum of P dt): the same comparison for the power the coupling receives
    p3 = res.conductor_power[:, 0] * model.symmetry_factor
    heat_err = p3.sum() / p2.sum() - 1
    print(f"disk Joule heat: 2D {p2.sum() * dt:.4f} J, 3D {p3.sum() * dt:.4f} J ({heat_err:+.2%})")
    assert abs(heat_err) < 0.02
    p_el = res.joule_density[-1] @ mesh.volumes(res.elements)
    assert p_el == pytest.approx(res.conductor_power[-1, 0], rel=1e-9)
    # per-tetrahedron force densities add up to the conductor's force (the coupling's input)
    f_el = (res.force_density[-1] * mesh.volumes(res.elements)[:, None]).sum(0)
    np.testing.assert_allclose(f_el, res.conductor_force[-1, 0], rtol=1e-9, atol=1e-9 * f2.max())
