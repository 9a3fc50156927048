"""3D deck: the current direction of a CLOSED coil from a cut (``Coil_DirType = 3``, ``Coil3D(direction="cut")``).

A whole ring coil (360 degrees, no symmetry plane) of section 5 mm x 4 mm (r 20..25 mm, z -2..2 mm),
one turn, meshed by ``closed_ring_mesh`` with its cut, the face y = 0, x > 0 inside the ring (physical
701), conforming with the tetrahedra. The cut run's direction is -grad v / |grad v|, v jumping by 1
across the cut (GetDP's ``OnPositiveSideOf`` and ``BF_GroupOfNodes``); its reference is the azimuthal
direction (``Coil_DirType = 0``, e_phi exactly) on the same mesh and with the same section, and
Biot-Savart of the rectangular ring (``test_coil_field.biot_savart``) for B_z at the centre (the ball
mean of ``test_em3d_static``: the ball of 5 mm is current-free, B_z harmonic there).

Measured on the 15.8k-tetrahedra mesh of ``_ring_mesh`` (h 2 mm in the coil, 4 mm at the centre, 30 mm at
the sphere): the cut direction is within 6.3 deg of e_phi on every coil tetrahedron (rms 1.66 deg:
the P1 gradient's O(h / R) error, uniform along the ring, no trace of the cut: 1.77 deg rms within 5 deg
of it); B_z at the centre: cut vs azimuthal +7.3e-4, magnetic energy -4.1e-4; vs Biot-Savart -1.66 %
(cut) and -1.74 % (azimuthal: the mesh's own error; -1.1 % on a 24k mesh, 2 mm at the centre).
Reversing the cut (its triangles in the file, or ``cut_normal``) reverses the current exactly
(B and energy to 1e-9). With a conducting disk 1 mm above the ring (transient, 3 steps): the disk's
axial force differs from the azimuthal run's by 1.2e-3 of its peak (bound 5e-3; 2.8e-3 and 4.2e-3 on
two other meshes), its Joule power likewise. In the persistent process (a cut coil on the capacitor bank)
the results equal the one-process BDF2 run's to 2e-14. Two disjoint turns in one coil region
(a free constant per turn in the pre-solve): B_z +1.6e-3 and energy +8.4e-4 vs azimuthal.
"""
from dataclasses import replace

import numpy as np
import pytest

from pulseform.solvers.getdp import Circuit, Conductor, DampedSine, Rect
from pulseform.solvers.getdp.conductivity import LinearResistivity
from pulseform.solvers.getdp.mesh3d import cut_orientation, cut_tag, physical_surface_area, read_surface_triangles
from pulseform.solvers.getdp.solver3d import Coil3D, EM3DModel, ball_average, model_numbers, solve_transient3d

from closed_ring_mesh import closed_ring_mesh, flip_physical_triangles
from getdp_testlib import needs_getdp
from test_coil_field import biot_savart

RING = Rect(0.020, -0.002, 0.025, 0.002)
SECTION = 20e-6
I_DC = 1e4
DISK = Rect(0.0, 0.003, 0.035, 0.004)


def _ring_mesh(path, **kw):
    return closed_ring_mesh(path, RING, h_coil=2e-3, h_air=0.03, h_centre=4e-3, **kw)


def _static(mesh, work, direction, cut_normal=None, sign=1):
    coil = Coil3D(1, waveform=DampedSine(I_DC, 0.0, 0.0, np.pi / 2), direction=direction, cut_normal=cut_normal,
                  sign=sign, section=SECTION if direction == "azimuthal" else None)
    model = EM3DModel(coils=[coil], shell=(0.1, 0.125), sector_deg=360.0)
    res = solve_transient3d(model, mesh, 1e-6, 1, work, field_output=True, direction_output=True)
    b, n = ball_average(mesh, res.b_cells, (0.0, 0.0, 0.0), 5e-3)
    return res, b


def _azimuth(mesh):
    c = mesh.centroids()
    return np.stack([-c[:, 1], c[:, 0], 0 * c[:, 0]], 1) / np.hypot(c[:, 0], c[:, 1])[:, None]


# ------------------------------------------------------------------ the cut's geometry (no getdp)
def test_cut_area_orientation_and_numbers(tmp_path):
    """The cut's area from the file's triangles is the rectangle's (the coil's section); its orientation is
    checked (consistent, or an error) and gives the sign of the deck; the deck numbers carry both."""
    mesh = _ring_mesh(tmp_path / "ring.msh")
    assert physical_surface_area(mesh.path, cut_tag(1)) == pytest.approx(SECTION, rel=1e-12)
    points, tri = read_surface_triangles(mesh.path, cut_tag(1))
    assert np.abs(points[:, 1]).max() < 1e-12        # the cut lies in the plane y = 0 ...
    assert points[:, 0].min() > 0                     # ... on the side x > 0
    normals = np.cross(points[tri[:, 1]] - points[tri[:, 0]], points[tri[:, 2]] - points[tri[:, 0]])
    mesh_sign = int(np.sign(normals[:, 1].sum()))     # +1 or -1: as gmsh wrote them
    assert np.all(np.sign(normals[:, 1]) == mesh_sign)
    assert cut_orientation(mesh.path, cut_tag(1)) == 1
    assert cut_orientation(mesh.path, cut_tag(1), (0.0, 1.0, 0.0)) == mesh_sign
    assert cut_orientation(mesh.path, cut_tag(1), (0.0, -2.0, 0.3)) == -mesh_sign
    with pytest.raises(ValueError, match="tangent"):
        cut_orientation(mesh.path, cut_tag(1), (1.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="no triangles"):
        cut_orientation(mesh.path, cut_tag(2))
    coil = Coil3D(3, waveform=DampedSine(1.0, 0.0, 0.0), direction="cut", cut_normal=(0.0, 1.0, 0.0))
    nb, _ = model_numbers(EM3DModel(coils=[coil]), mesh)
    assert nb["Coil_DirType_1"] == 3 and nb["Phys_Cut_Base"] == 700
    assert nb["Coil_Sc_1"] == pytest.approx(SECTION, rel=1e-12) and nb["Coil_CutSign_1"] == mesh_sign
    nb_az, _ = model_numbers(EM3DModel(coils=[Coil3D(3, waveform=DampedSine(1.0, 0.0, 0.0))]), mesh)
    assert not any(k.startswith("Coil_CutSign") for k in nb_az)   # the other directions pass what they did
    with pytest.raises(ValueError, match="cut_normal"):
        Coil3D(1, waveform=DampedSine(1.0, 0.0, 0.0), cut_normal=(0.0, 1.0, 0.0))
    # half of the cut's triangles reversed: refused (GetDP would only warn and mix the sides)
    bad = tmp_path / "bad.msh"
    text = mesh.path.read_text()
    head, rest = text.split("$Elements\n", 1)
    body, tail = rest.split("$EndElements", 1)
    count, rows = body.split("\n", 1)
    out, n_cut = [], 0
    for line in rows.splitlines():
        r = line.split()
        if len(r) > 3 and r[1] == "2" and int(r[3]) == cut_tag(1):
            n_cut += 1
            if n_cut % 2:
                r[-2], r[-1] = r[-1], r[-2]
            line = " ".join(r)
        out.append(line)
    bad.write_text(f"{head}$Elements\n{count}\n" + "\n".join(out) + f"\n$EndElements{tail}")
    with pytest.raises(ValueError, match="consistently oriented"):
        cut_orientation(bad, cut_tag(1))


# ------------------------------------------------------------------ static ring
@pytest.mark.getdp
@needs_getdp
def test_closed_ring_cut_direction_vs_azimuthal_and_biot_savart(work):
    """The cut's direction is e_phi up to the P1 gradient's error, the centre field and the energy equal the
    azimuthal run's, and both equal Biot-Savart's within the mesh's error; the current crosses the cut
    along ``cut_normal`` = +e_y (= +e_phi on the cut): B_z > 0 at the centre."""
    mesh = _ring_mesh(work / "ring.msh")
    az, b_az = _static(mesh, work / "az", "azimuthal")
    cut, b_cut = _static(mesh, work / "cut", "cut", cut_normal=(0.0, 1.0, 0.0))
    assert cut.n_dofs == az.n_dofs                     # the magnetic system's count, not the pre-solve's
    assert np.allclose(cut.coil_current[-1, 0], I_DC, rtol=1e-12)
    coil = np.flatnonzero(mesh.tet_tags == 101)
    assert np.all(np.isfinite(cut.coil_dir[coil])) and np.isnan(cut.coil_dir[mesh.tet_tags == 1]).all()
    dot = np.einsum("ij,ij->i", cut.coil_dir[coil], _azimuth(mesh)[coil])
    ang = np.degrees(np.arccos(np.clip(dot, -1.0, 1.0)))
    rms = float(np.sqrt(np.mean(ang ** 2)))
    ref = biot_savart([RING], I_DC, 1e-6, 0.0)[1]
    d_b, d_w = b_cut[2] / b_az[2] - 1, cut.magnetic_energy[-1] / az.magnetic_energy[-1] - 1
    print(f"\nclosed ring, {mesh.n_tets} tets, {cut.n_dofs} dofs: direction vs e_phi max {ang.max():.2f} deg, rms "
          f"{rms:.2f} deg; B_z centre cut {b_cut[2]:.6f} T, azimuthal {b_az[2]:.6f} T ({d_b:+.2e}), Biot-Savart "
          f"{ref:.6f} T (cut {b_cut[2] / ref - 1:+.3%}, azimuthal {b_az[2] / ref - 1:+.3%}); energy "
          f"{cut.magnetic_energy[-1]:.6f} J vs {az.magnetic_energy[-1]:.6f} J ({d_w:+.2e})")
    assert ang.max() < 10.0 and rms < 2.5             # measured 6.3 deg, 1.66 deg (O(h / R) of P1)
    assert b_cut[2] > 0
    assert abs(d_b) < 2e-3 and abs(d_w) < 2e-3        # measured +7.3e-4, -4.1e-4
    assert abs(b_cut[2] / ref - 1) < 0.025 and abs(b_az[2] / ref - 1) < 0.025   # measured -1.66 %, -1.74 %


# slow (four more static solves of the cut ring; in the default tier the cut's orientation, cut_normal and sign
# are checked in the deck's numbers by test_cut_area_orientation_and_numbers and the cut's current in getdp by
# test_closed_ring_cut_direction_vs_azimuthal_and_biot_savart)
@pytest.mark.slow
@pytest.mark.getdp
@needs_getdp
def test_reversing_the_cut_reverses_the_current(work):
    """The current crosses the cut along its triangles' normal without ``cut_normal``: the same mesh with
    the cut's triangles reversed (the file rewritten) gives the opposite current, exactly; ``cut_normal``
    fixes the sense whatever the triangles' orientation (on one of the two files the deck's
    ``Coil_CutSign`` is then -1, on the other +1), and ``Coil3D.sign`` = -1 reverses it."""
    mesh = _ring_mesh(work / "ring.msh")
    flipped = _ring_mesh(work / "ring_flipped.msh", flip_cut=True)
    assert np.array_equal(mesh.tets, flipped.tets) and np.array_equal(mesh.points, flipped.points)
    s = cut_orientation(mesh.path, cut_tag(1), (0.0, 1.0, 0.0))   # the sign of the mesh's normal along +y
    assert cut_orientation(flipped.path, cut_tag(1), (0.0, 1.0, 0.0)) == -s
    natural, b_nat = _static(mesh, work / "natural", "cut")
    natural_f, b_nat_f = _static(flipped, work / "natural_flipped", "cut")
    plus, b_plus = _static(mesh, work / "plus", "cut", cut_normal=(0.0, 1.0, 0.0))
    plus_f, b_plus_f = _static(flipped, work / "plus_flipped", "cut", cut_normal=(0.0, 1.0, 0.0), sign=-1)
    print(f"\nB_z centre: mesh's normal {b_nat[2]:+.6f} T, reversed triangles {b_nat_f[2]:+.6f} T, "
          f"cut_normal +y {b_plus[2]:+.6f} T, cut_normal +y on reversed triangles with sign -1 {b_plus_f[2]:+.6f} T")
    tol = 1e-9 * abs(b_nat[2])
    assert np.sign(b_nat[2]) == s                     # along the mesh's normal (+e_phi on the cut: B_z > 0)
    np.testing.assert_allclose(natural_f.b_cells, -natural.b_cells, rtol=0, atol=tol)
    np.testing.assert_allclose(natural_f.coil_dir, -natural.coil_dir, rtol=0, atol=1e-9, equal_nan=True)
    assert natural_f.magnetic_energy[-1] == pytest.approx(natural.magnetic_energy[-1], rel=1e-9)
    assert b_plus[2] > 0 and b_plus_f[2] < 0
    np.testing.assert_allclose(plus.b_cells, s * natural.b_cells, rtol=0, atol=tol)
    np.testing.assert_allclose(plus_f.b_cells, -plus.b_cells, rtol=0, atol=tol)


@pytest.mark.getdp
@needs_getdp
def test_two_turns_in_one_region(work):
    """Two disjoint rings (r 20-24 mm and 27-31 mm, z +-2 mm) in ONE coil region, the cut spanning both:
    the pre-solve's potential has a free constant per turn (fixed by the deck's gauge penalty); the
    section is both rectangles; B_z at the centre and the energy vs the azimuthal run on the same mesh.
    Measured: +1.6e-3 and +8.4e-4 (the inner turn 4 mm wide, 2 mm elements); Biot-Savart -1.6 %."""
    turns = [Rect(0.020, -0.002, 0.024, 0.002), Rect(0.027, -0.002, 0.031, 0.002)]
    mesh = closed_ring_mesh(work / "two.msh", turns, h_coil=2e-3, h_air=0.03, h_centre=4e-3)
    assert physical_surface_area(mesh.path, cut_tag(1)) == pytest.approx(32e-6, rel=1e-12)
    runs = {}
    for direction in ("azimuthal", "cut"):
        coil = Coil3D(2, waveform=DampedSine(I_DC, 0.0, 0.0, np.pi / 2), direction=direction,
                      cut_normal=(0.0, 1.0, 0.0) if direction == "cut" else None,
                      section=32e-6 if direction == "azimuthal" else None)
        res = solve_transient3d(EM3DModel(coils=[coil], shell=(0.1, 0.125)), mesh, 1e-6, 1, work / direction,
                                field_output=True)
        runs[direction] = (ball_average(mesh, res.b_cells, (0.0, 0.0, 0.0), 5e-3)[0][2], res.magnetic_energy[-1])
    ref = biot_savart(turns, I_DC, 1e-6, 0.0)[1]
    d_b = runs["cut"][0] / runs["azimuthal"][0] - 1
    d_w = runs["cut"][1] / runs["azimuthal"][1] - 1
    print(f"\ntwo turns in one region, {mesh.n_tets} tets: B_z cut vs azimuthal {d_b:+.2e}, energy {d_w:+.2e}; "
          f"vs Biot-Savart {runs['cut'][0] / ref - 1:+.3%}")
    assert abs(d_b) < 4e-3 and abs(d_w) < 4e-3
    assert abs(runs["cut"][0] / ref - 1) < 0.025


# ------------------------------------------------------------------ transient: a disk above the ring
@pytest.mark.getdp
@needs_getdp
def test_disk_above_closed_ring_force_vs_azimuthal(work):
    """A conducting disk (r 35 mm, 1 mm thick, 1 mm above the ring) and 20 kA e^(-1e4 t) sin(1e5 t), 3 implicit
    Euler steps of 2 us on a coarse mesh: the disk's axial force and Joule power, cut vs azimuthal.
    Measured (largest difference of F_z over the steps / its peak): 1.2e-3 on this mesh (14.3k tetrahedra,
    h 2 mm in the coil); 2.8e-3 with h 1.5 mm, 4.2e-3 with 2.5 mm (5 steps): the P1 direction's noise."""
    mesh = closed_ring_mesh(work / "disk.msh", RING, disk=DISK, h_coil=2e-3, h_disk=4e-3, h_air=0.04,
                            h_centre=None)
    wave = DampedSine(20e3, 1e4, 1e5)
    runs = {}
    for direction in ("azimuthal", "cut"):
        coil = Coil3D(1, waveform=wave, direction=direction, cut_normal=(0.0, 1.0, 0.0) if direction == "cut" else None,
                      section=SECTION if direction == "azimuthal" else None)
        model = EM3DModel(coils=[coil], conductors=[Conductor(3.5e7)], shell=(0.1, 0.125))
        runs[direction] = solve_transient3d(model, mesh, 6e-6, 3, work / direction, element_output="none")
    fz = {d: r.conductor_force[:, 0, 2] for d, r in runs.items()}
    p = {d: r.conductor_power[:, 0] for d, r in runs.items()}
    d_f = np.abs(fz["cut"] - fz["azimuthal"]).max() / np.abs(fz["azimuthal"]).max()
    d_p = np.abs(p["cut"] - p["azimuthal"]).max() / np.abs(p["azimuthal"]).max()
    f_xy = np.abs(runs["cut"].conductor_force[:, 0, :2]).max() / np.abs(fz["cut"]).max()
    print(f"\ndisk above the closed ring, {mesh.n_tets} tets: F_z azimuthal {np.array2string(fz['azimuthal'], precision=1)} N,"
          f" cut {np.array2string(fz['cut'], precision=1)} N: max difference {d_f:.2e} of the peak; Joule power "
          f"{d_p:.2e}; in-plane force of the cut run {f_xy:.1e} of F_z")
    assert fz["azimuthal"].max() > 100.0               # repulsion of the order of kN
    assert d_f < 5e-3 and d_p < 1e-2
    assert f_xy < 1e-2


# ------------------------------------------------------------------ persistent getdp
def _persistent_rows(model, mesh, n: int, t_end: float, folder):
    """F_z (N), coil current (A), capacitor voltage (V), magnetic energy (J) of ``n`` equal steps to ``t_end`` (s) of
    the persistent 3D process on the fixed ``mesh``, and its last state."""
    from pulseform.solvers.getdp.persistent3d import PersistentEM3DStepper

    stepper = PersistentEM3DStepper(model, folder)
    state, rows = stepper.initial_state(), []
    try:
        for k in range(1, n + 1):
            r, state = stepper.step(mesh, state, k * t_end / n)
            rows.append([r.conductor_force[-1, 0, 2], r.coil_current[-1, 0], r.capacitor_voltage[-1],
                         r.magnetic_energy[-1]])
    finally:
        stepper.close()
    return rows, state


@pytest.mark.getdp
@needs_getdp
def test_cut_coil_in_the_persistent_process(work):
    """A cut coil on the capacitor bank in the persistent 3D process (its pre-solve's system after U) equals
    the one-process BDF2 run on the fixed mesh to round-off (the bound of test_persistent3d)."""
    mesh = closed_ring_mesh(work / "disk.msh", RING, disk=DISK, h_coil=3e-3, h_disk=4e-3, h_air=0.04, h_centre=None)
    model = EM3DModel(coils=[Coil3D(1, direction="cut", cut_normal=(0.0, 1.0, 0.0))], conductors=[Conductor(3.5e7)],
                      circuit=Circuit(50e-6, 6e3, 0.01, 2e-6), shell=(0.1, 0.125))
    n, t_end = 3, 3e-6
    full = solve_transient3d(model, mesh, t_end, n, work / "full", time_scheme="bdf2", element_output="none")
    rows, _ = _persistent_rows(model, mesh, n, t_end, work / "persistent")
    ref = np.column_stack([full.conductor_force[:, 0, 2], full.coil_current[:, 0], full.capacitor_voltage,
                           full.magnetic_energy])
    rel = (np.abs(np.array(rows) - ref).max(axis=0) / np.abs(ref).max(axis=0)).max()
    print(f"\npersistent vs one process, cut coil on the bank, {mesh.n_tets} tets: {rel:.1e}; "
          f"I {ref[:, 1]} A, F_z {ref[:, 0]} N")
    assert ref[-1, 1] > 0 and ref[-1, 0] > 0           # the bank drives a positive current: repulsion
    assert rel < 1e-12
    # the coil's σ(T) through the step messages (a law held at 293.15 K: σ_ref = the constant's 5.8e7 S/m): the
    # pre-solve of the cut reads sigma[] before the first message (PF_InitSigma, Lib_PersistentSigma.pro), the
    # steps the messages' σ; the same doubles as the constant run
    law = replace(model, coils=[Coil3D(1, direction="cut", cut_normal=(0.0, 1.0, 0.0), heat_capacity=1e300,
                                       conductivity_law=LinearResistivity(5.8e7, 3.9e-3, 293.15))])
    rows_law, state = _persistent_rows(law, mesh, n, t_end, work / "persistent_law")
    assert state.coil_sigma == [5.8e7]
    assert np.array_equal(np.array(rows_law), np.array(rows))
