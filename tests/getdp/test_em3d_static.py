"""3D deck (Lib_PulsedForming3D.pro): static field of a circular coil vs Biot-Savart.

The demo's 5-turn coil (turns 4 mm x 3 mm, inner radius 12 mm, 2 mm apart, z from -4 to -1 mm,
``demo_coil_turns``) carries a direct current of 10 kA per turn; a 30 degree sector with its two
meridian planes as symmetry planes (n x a = 0), air sphere 100 mm, shell to 125 mm. No conductor:
the run is the static field.

Reference: Biot-Savart of circular filaments (complete elliptic integrals) integrated over each
turn's rectangular section with 8 x 8 Gauss points (``test_coil_field.biot_savart``, itself
checked against a direct Biot-Savart sum there), B_z at the coil's centre (0, 0, -2.5 mm).

What the 3D solution gives at the centre: lowest-order edge elements have a piecewise constant B,
so the value is the volume average of B_z over the tetrahedra whose centroids lie within 4 mm of
the centre. The ball is current-free (the turns start at r = 12 mm) and B_z is harmonic there,
so its mean over a ball (or any sector of a ball, the field being axisymmetric) equals its value
at the centre: the average measures the centre field, not a smoothed one.

Observed (this mesh generator, azimuthal direction): -0.47 % (4.1k tetrahedra), -0.79 % (6.3k),
-0.54 % (9.6k), -0.43 % (25.9k; 2D axisymmetric on the same shell: -0.09 %); electrokinetic
direction on the 9.6k mesh: -0.51 %; the upper half (n x h = 0 on the mid-plane), 6.7k: -0.48 %.
The issue's bar is 1 %. (The half ball of the half model has the same mean: B_z is even in z - z_c.)
"""
import numpy as np
import pytest

from pulseform.solvers.getdp import DampedSine, Rect
from pulseform.solvers.getdp.mesh3d import ring_sector_mesh
from pulseform.solvers.getdp.solver3d import Coil3D, EM3DModel, ball_average, coil_section_from_mesh, solve_transient3d

from getdp_testlib import needs_getdp
from test_coil_field import biot_savart

I_TURN = 1e4
Z_CENTRE = -0.0025


def demo_coil_turns() -> list:
    """The demo's coil (cases/emf_fixed_disk): 5 turns 4 mm x 3 mm from r = 12 mm, 2 mm apart, z -4..-1 mm."""
    return [Rect(0.012 + i * 0.006, -0.004, 0.016 + i * 0.006, -0.001) for i in range(5)]


@pytest.mark.getdp
@needs_getdp
@pytest.mark.parametrize("direction, half", [("azimuthal", False), ("electrokinetic", False), ("azimuthal", True)])
def test_centre_field_vs_biot_savart_3d_sector(work, direction, half):
    """The coil's current direction from the geometry (e_phi) or from the electrokinetic pre-solve
    (-grad v / |grad v|, v = 1 / 0 on the turns' faces on the two symmetry planes); ``half``: only
    z >= z_c is meshed, the coil's mid-plane z = z_c being a symmetry plane of type n x h = 0 (B normal
    to it: nothing imposed), so the model is 1/24 of the coil."""
    turns = demo_coil_turns()
    mesh = ring_sector_mesh(work / "coil3d.msh", turns, [], sector_deg=30.0, r_air=0.1, r_shell=0.125,
                            h_coil=1.5e-3, h_air=0.015, h_centre=0.7e-3, z_cut=Z_CENTRE if half else None)
    part = 0.5 if half else 1.0
    # mesh section of the rings (sum V / (r alpha)) vs the exact rectangles: the faceted rings
    assert coil_section_from_mesh(mesh, 1) == pytest.approx(part * 5 * 12e-6, rel=2e-3)
    assert mesh.electrode_area[1] == pytest.approx(part * 5 * 12e-6, rel=1e-12)   # the turns' plane faces
    coil = Coil3D(5, waveform=DampedSine(I_TURN, 0.0, 0.0, np.pi / 2), direction=direction,
                  section=5 * 12e-6 if half else None)   # a cut coil keeps its whole section
    model = EM3DModel(coils=[coil], shell=(0.1, 0.125), sector_deg=30.0, symmetry_factor=12 / part)
    res = solve_transient3d(model, mesh, 1e-6, 1, work / "run", field_output=True)
    assert np.allclose(res.coil_current[-1, 0], I_TURN, rtol=1e-12)
    b, n = ball_average(mesh, res.b_cells, (0.0, 0.0, Z_CENTRE), 4e-3)
    ref = biot_savart(turns, I_TURN, 1e-6, Z_CENTRE)[1]
    err = b[2] / ref - 1
    print(f"\n{direction}{' half (n x h = 0)' if half else ''}: 3D sector 30 deg, {mesh.n_tets} tets, {res.n_dofs} dofs: B_z centre {b[2]:.6f} T "
          f"(mean of {n} tets), Biot-Savart {ref:.6f} T, rel. error {err:+.3%}; "
          f"{res.wall_per_step:.2f} s per step")
    assert abs(err) < 0.01
    # B_r is odd in z - z_c about the coil's mid-plane (B_r ~ -(r/2)(z - z_c) d2B_z/dz2 near the centre),
    # so its mean over the (whole) ball vanishes: what is left is discretisation noise
    if not half:
        assert abs(b[0]) < 0.02 * ref and abs(b[1]) < 0.02 * ref


@pytest.mark.getdp
@needs_getdp
def test_far_boundary_without_shell_vs_axisymmetric(work):
    """n x a = 0 on the sphere r = 50 mm, no shell: the truncated problem, whose reference is our 2D
    axisymmetric solver with a = 0 on the same circle (fine 0.5 mm mesh); Biot-Savart shows how much
    the truncation itself costs (several %), which both solvers must reproduce alike (bar 1 %)."""
    from pulseform.solvers.getdp import Coil, CurrentTable, EMModel, GetDPSolver, coil_conductor_mesh

    turns, r_far = demo_coil_turns(), 0.05
    mesh2 = coil_conductor_mesh([turns], [], r_domain=r_far, h_fine=5e-4, h_coarse=3e-3)
    model2 = EMModel(True, coils=[Coil(5, waveform=CurrentTable([0, 1], [I_TURN, I_TURN]))], probes=[(1e-5, Z_CENTRE)])
    solver2 = GetDPSolver(model2, work / "axi")
    res2, _ = solver2.step(mesh2, solver2.initial_state(), 1e-6, 1)
    ref = -res2.probe_b[-1, 0, 1]   # GetDP's 2D frame: a positive coil current flows along -e_phi
    mesh = ring_sector_mesh(work / "coil3d.msh", turns, [], sector_deg=30.0, r_air=r_far, r_shell=None,
                            h_coil=1.5e-3, h_air=0.01, h_centre=0.7e-3)
    model = EM3DModel(coils=[Coil3D(5, waveform=DampedSine(I_TURN, 0.0, 0.0, np.pi / 2))], sector_deg=30.0)
    res = solve_transient3d(model, mesh, 1e-6, 1, work / "run", field_output=True)
    b, n = ball_average(mesh, res.b_cells, (0.0, 0.0, Z_CENTRE), 4e-3)
    bs = biot_savart(turns, I_TURN, 1e-6, Z_CENTRE)[1]
    err = b[2] / ref - 1
    print(f"\na = 0 at {r_far * 1e3:g} mm: 3D {b[2]:.6f} T ({mesh.n_tets} tets), 2D {ref:.6f} T ({mesh2.n_nodes} nodes): "
          f"{err:+.3%}; vs Biot-Savart (open space) 3D {b[2] / bs - 1:+.2%}, 2D {ref / bs - 1:+.2%}")
    assert ref / bs - 1 < -0.02          # the truncation is visible ...
    assert abs(err) < 0.01               # ... and the same in both solvers


@pytest.mark.getdp
@needs_getdp
# the azimuthal direction slow: order 2 on this mesh runs in the default tier with the electrokinetic direction, the
# azimuthal direction there at order 1 (test_centre_field_vs_biot_savart_3d_sector)
@pytest.mark.parametrize("direction", [pytest.param("azimuthal", marks=pytest.mark.slow), "electrokinetic"])
def test_centre_field_order2_vs_biot_savart(work, direction):
    """Second-order edge elements (``EM3DModel.order = 2``: B linear per tetrahedron) on the same 9.6k mesh:
    the same Biot-Savart reference and ball mean (the mean of a linear B over a tetrahedron is its value at
    the centroid, which ``b_cells`` holds). Observed: order 1 -0.54 % / -0.50 % (azimuthal /
    electrokinetic), order 2 +0.015 % / +0.048 % (8.4k / 44.5k dofs). Checked: order 2 within 0.2 % and
    at least 4 times closer than order 1."""
    turns = demo_coil_turns()
    mesh = ring_sector_mesh(work / "coil3d.msh", turns, [], sector_deg=30.0, r_air=0.1, r_shell=0.125,
                            h_coil=1.5e-3, h_air=0.015, h_centre=0.7e-3)
    ref = biot_savart(turns, I_TURN, 1e-6, Z_CENTRE)[1]
    err = {}
    for order in (1, 2):
        coil = Coil3D(5, waveform=DampedSine(I_TURN, 0.0, 0.0, np.pi / 2), direction=direction)
        model = EM3DModel(coils=[coil], shell=(0.1, 0.125), sector_deg=30.0, order=order)
        res = solve_transient3d(model, mesh, 1e-6, 1, work / f"run{order}", field_output=True)
        b, n = ball_average(mesh, res.b_cells, (0.0, 0.0, Z_CENTRE), 4e-3)
        err[order] = b[2] / ref - 1
        print(f"\n{direction}, order {order}: {mesh.n_tets} tets, {res.n_dofs} dofs: B_z centre {b[2]:.6f} T, "
              f"Biot-Savart {ref:.6f} T, rel. error {err[order]:+.3%}")
    assert abs(err[2]) < 0.002
    assert abs(err[2]) < abs(err[1]) / 4
