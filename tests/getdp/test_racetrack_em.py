"""3D EM on the racetrack / sheet / grooved-die model (issue 20, case b): the coil's field against an
independent Biot–Savart integration, the symmetry plane x = 0, and (slow) mesh convergence of the
sheet's peak force under the bank discharge.

References:
- racetrack_biot_savart.racetrack_b (this folder): uniform current density over each turn's section,
  closed-form straight-line fields along the straight sides, composite Gauss over the half circles;
  checked here against the elliptic-integral ring formula (zero straight length) and against
  test_em3d_racetrack's polygon filaments. The FE and reference values are means over the same
  tetrahedra (the FE's B is constant per tetrahedron; the reference by a 4-point rule per tetrahedron).
- the symmetry check compares the quarter with the half model made of the same quarter mesh and its
  mirror image (racetrack_mirror): the same discretisation, so the difference is the plane's.
"""
import json
import os

import numpy as np
import pytest

from pulseform.solvers.getdp import Circuit, Conductor, DampedSine, Rect
from pulseform.solvers.getdp.racetrack_mesh import RacetrackGroove, racetrack_groove_mesh
from pulseform.solvers.getdp.racetrack_mirror import mirror_quarter
from pulseform.solvers.getdp.solver3d import Coil3D, EM3DModel, solve_transient3d

from getdp_testlib import needs_getdp
from racetrack_biot_savart import racetrack_b, tet_average
from test_coil_field import biot_savart
from test_em3d_racetrack import racetrack_field

I_TURN = 1e4
BANK = Circuit(C=50e-6, V0=6e3, R_ext=0.01, L_ext=0.5e-6)
SIGMA_AL, SIGMA_STEEL = 2.5e7, 1.4e6


def bank_model(g: RacetrackGroove, sector_deg: float) -> EM3DModel:
    return EM3DModel(coils=[Coil3D(g.turns, direction="electrokinetic")],
                     conductors=[Conductor(SIGMA_AL), Conductor(SIGMA_STEEL)], circuit=BANK,
                     shell=(g.air_radius, g.shell_radius), sector_deg=sector_deg)


def test_reference_matches_ring_formula_and_filaments():
    # zero straight length: one ring of rectangular section, elliptic integrals (test_coil_field)
    p = np.array([[0.0095, 0.0, 0.0005], [0.004, 0.0, -0.003]])
    b = racetrack_b(p, [(0.008, 0.011)], (-0.005, -0.001), 0.0, I_TURN)
    for q, bb in zip(p, b):
        br, bz = biot_savart([Rect(0.008, -0.005, 0.011, -0.001)], I_TURN, q[0], q[2], n_gauss=16)
        # the default quadrature rule's error 1.5 mm from the turn: 3.5e-6 (negligible beside the FE's 1 %)
        np.testing.assert_allclose([bb[0], bb[2]], [br, bz], rtol=1e-5, atol=1e-9)
    # the default racetrack vs 8 x 8 polygon filaments per turn (test_em3d_racetrack), near and far points
    g = RacetrackGroove()
    turns = [g.turn_x(i) for i in range(g.turns)]
    pts = np.array([[0.0135, 0.005, 0.0005], [0.002, 0.037, 0.0005], [0.0, 0.0, -0.003], [0.02, 0.03, 0.003]])
    b = racetrack_b(pts, turns, g.coil_z, g.half_straight, I_TURN)
    for q, bb in zip(pts, b):
        ref = racetrack_field([Rect(a, g.coil_z[0], c, g.coil_z[1]) for a, c in turns], g.half_straight, I_TURN, q,
                              n_gauss=8)
        np.testing.assert_allclose(bb, ref, rtol=0, atol=2e-6 * np.linalg.norm(ref))


# slow (a 44k-tetrahedra validation; its code is covered in the default tier by a racetrack coil's field
# (electrokinetic direction) vs Biot-Savart: tests/getdp/test_em3d_racetrack.py::test_racetrack_centre_field_vs_biot_savart)
@pytest.mark.slow
@pytest.mark.getdp
@needs_getdp
def test_coil_field_vs_biot_savart(work):
    """Direct current, no conductors (sheet and die meshed as air), mesh 0.8 x the default sizes (44k tets).

    Observed (main component of the mean B over the window; default mesh 24k / 0.8: 44k / 0.6: 96k tets):
    centre ball -1.42 / -0.87 / -0.58 %; sheet over the straight sides -0.53 / -0.59 / -0.59 %; sheet over
    the bend -1.81 / -1.11 / -0.83 %; groove -1.11 / -0.87 / -0.45 %. Bar 1.5 % (the issue: 1-2 %).
    """
    g = RacetrackGroove().scaled(0.8)
    mesh = racetrack_groove_mesh(work / "coil_only.msh", g, conductors=False)
    model = EM3DModel(coils=[Coil3D(g.turns, waveform=DampedSine(I_TURN, 0.0, 0.0, np.pi / 2),
                                    direction="electrokinetic")], shell=(g.air_radius, g.shell_radius), sector_deg=90.0)
    res = solve_transient3d(model, mesh, 1e-6, 1, work / "run", field_output=True, element_output="none")
    c, H, t, zd = mesh.centroids(), g.half_straight, g.sheet_thickness, g.die_z[0]
    x0, x1 = g.bend_radius, g.coil_outer
    in_sheet = (c[:, 2] > 0) & (c[:, 2] < t)
    windows = {   # name: (tetrahedra, main component)
        "centre ball": (np.linalg.norm(c - [0, 0, np.mean(g.coil_z)], axis=1) < 4e-3, 2),
        "sheet over the straight sides": (in_sheet & (c[:, 0] > x0) & (c[:, 0] < x1) & (c[:, 1] < 15e-3), 0),
        "sheet over the bend": (in_sheet & (c[:, 0] < 6e-3) & (c[:, 1] > H + x0) & (c[:, 1] < H + x1), 1),
        "groove": ((c[:, 2] > zd) & (c[:, 2] < zd + g.groove_depth) & (c[:, 0] > g.groove_x[0])
                   & (c[:, 0] < g.groove_x[1]) & (c[:, 1] < g.groove_half_length), 0),
    }
    turns = [g.turn_x(i) for i in range(g.turns)]
    errors = {}
    for name, (sel, k) in windows.items():
        rows = np.flatnonzero(sel)
        v = mesh.volumes(rows)
        fe = (res.b_cells[rows] * v[:, None]).sum(0) / v.sum()
        ref = tet_average(mesh.points, mesh.tets[rows], lambda q: racetrack_b(q, turns, g.coil_z, H, I_TURN))
        errors[name] = fe[k] / ref[k] - 1
        print(f"\n{name}: {rows.size} tets, B_{'xyz'[k]} FE {fe[k]:.5f} T, Biot-Savart {ref[k]:.5f} T, "
              f"error {errors[name]:+.2%}, |B_FE - B_ref| / |B_ref| {np.linalg.norm(fe - ref) / np.linalg.norm(ref):.2%}")
    print(f"{mesh.n_tets} tets, {res.n_dofs} dofs")
    assert all(abs(e) < 0.015 for e in errors.values()), errors


@pytest.mark.getdp
@needs_getdp
@pytest.mark.parametrize("factor, bar", [pytest.param(2.0, 5e-3, id="coarse"),
                                         pytest.param(1.0, 5e-4, id="default", marks=pytest.mark.slow)])
def test_symmetry_plane_quarter_vs_mirrored_half(work, factor, bar):
    """Bank discharge into sheet and die: the quarter (n x a = 0 on x = 0 and y = 0) against the half
    made of the same mesh and its mirror (the plane y = 0 only), same circuit.

    Observed, sheet F_z over the steps (whole device): 2 x the default sizes (7.1k / 14.2k tets, 4 steps):
    0.19-0.24 %; default sizes (24.3k / 48.6k tets): 0.010-0.011 %, the current 4e-5 (the difference is
    the tree gauge's handling of the coil's discrete source, which falls with the mesh). Half models
    meshed on their own differ from the quarter by 2-4 % at these sizes: mesh-to-mesh scatter, see the
    convergence study in docs/em_geometries.md.
    """
    g = RacetrackGroove().scaled(factor)
    quarter = racetrack_groove_mesh(work / "quarter.msh", g)
    half = mirror_quarter(quarter, work / "half.msh")
    assert half.n_tets == 2 * quarter.n_tets
    runs = {}
    for m in (quarter, half):
        model = bank_model(g, m.sector_deg)
        r = solve_transient3d(model, m, 4e-6, 4, work / f"run{m.sector_deg:.0f}", element_output="none")
        runs[m.sector_deg] = (r.circuit_current, r.conductor_force[:, :, 2] * model.symmetry_factor,
                              r.conductor_force[:, 0, 0])
    (iq, fq, _), (ih, fh, fxh) = runs[90.0], runs[180.0]
    rel = np.abs(fq[:, 0] / fh[:, 0] - 1)
    print(f"\nquarter {quarter.n_tets} / half {half.n_tets} tets: sheet F_z {fq[-1, 0]:.1f} vs {fh[-1, 0]:.1f} N, "
          f"max rel. difference {rel.max():.2e}, current {np.abs(iq / ih - 1).max():.1e}, die F_z {fq[-1, 1]:.2f} vs "
          f"{fh[-1, 1]:.2f} N, half's F_x / F_z {abs(fxh[-1]) / fh[-1, 0]:.1e}")
    assert rel.max() < bar
    assert np.abs(iq / ih - 1).max() < bar
    assert abs(fxh[-1]) < 1e-3 * fh[-1, 0] / 2     # the half's sheet force has no x component (symmetry)


@pytest.mark.slow
@pytest.mark.getdp
@needs_getdp
def test_sheet_peak_force_mesh_convergence(work):
    """Sheet's peak F_z under the bank (30 steps of 1 us) on 2, 4/3 and 1 x the default sizes (sheet layers 2, 3, 4;
    7.1k, 14.5k, 24.3k tets), GCI by orchestrator/workflows/gci.py (Celik et al. 2008).

    Observed (2026-11-27, shared 2-vCPU machine): peak 13405, 26002, 31755 N (whole device, at 11, 10, 10 us),
    monotone, observed order 1.26, extrapolated 44976 N, GCI of the default mesh 52 %: the default mesh is not
    in the asymptotic range for the sheet force (in-plane size 2.5 mm against turns 3 mm wide at a 4 mm pitch);
    the die's peak (186 N) converges with order 1.9, GCI 14 %. CPU per step 0.20, 0.77, 2.31 s.
    """
    from pulseform.orchestrator.workflows.gci import grid_convergence

    peaks, h = [], [1.0, 4 / 3, 2.0]
    for f in h:
        g = RacetrackGroove().scaled(f)
        m = racetrack_groove_mesh(work / f"level{f:.2f}.msh", g)
        model = bank_model(g, 90.0)
        r = solve_transient3d(model, m, 30e-6, 30, work / f"run{f:.2f}", element_output="none")
        peaks.append(float((r.conductor_force[:, 0, 2] * model.symmetry_factor).max()))
        print(f"\nsizes x {f:.3f}: {m.n_tets} tets, {r.n_dofs} dofs, peak sheet F_z {peaks[-1]:.0f} N, "
              f"CPU {r.cpu_per_step:.2f} s per step")
    res = grid_convergence(h, peaks)
    print(json.dumps(res.to_dict()))
    assert res.convergence == "monotone" and res.order > 0.5
