"""The force on a magnetised body (issue 35, item 3): the surface force of :mod:`~pulseform.solvers.getdp.magnetic_force`.

Analytic (no getdp): a magnetised slab in a uniform field feels on each face the jump of the Maxwell stress,
½ (ν0 − ν) B_n² on the faces across the field and ½ (μ − μ0) H_t² on the faces along it, both pulling outwards;
in vacuum (μ_r = 1) nothing, to the last bit.

Against two independent evaluations of the same GetDP solution (getdp): an iron disk (radius 25 mm, 4 mm thick,
2 mm above a coil of 100 turns, axisymmetric, direct current, no eddy current: a non-conducting core) is pulled
towards the coil. References: the Maxwell stress of the air, ∮ ν0 ((B·n) B − ½ B² n) 2π r dl, on two closed
contours 0.5 mm and 1 mm around the disk (B of the triangle at each of 4000 points per side), and virtual work,
F_z = dW'/dz at constant current by central differences of the co-energy W' over two runs with the disk moved by
±0.1 mm (W' = GetDP's W + Σ_core (h b − 2 w) V: the co-energy of the air and shell is their energy).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pulseform.solvers.getdp import Coil, Conductor, DampedSine, EMModel, GetDPSolver, Rect, coil_conductor_mesh, slab_mesh
from pulseform.solvers.getdp.bh_curve import MU0
from pulseform.solvers.getdp.files import element_volumes
from pulseform.solvers.getdp.magnetic_force import material_laws, magnetisation_forces, model_magnetisation_forces
from pulseform.solvers.getdp.mesh import EMMesh, core_tag
from pulseform.solvers.getdp.model import MagneticCore

from getdp_testlib import needs_getdp
from test_magnetic import STEEL

COIL = [Rect(0.010, -0.006, 0.020, -0.001)]
Z0, THICK, RADIUS = 0.002, 0.004, 0.025


def _slab(mu_r: float, b: tuple[float, float]):
    """A 4 x 1 mm slab (planar) of 8 x 2 squares, the flux density ``b`` (T) in every triangle, and its forces."""
    x, y = np.meshgrid(np.linspace(0, 4e-3, 9), np.linspace(0, 1e-3, 3))
    pts = np.column_stack([x.ravel(), y.ravel()])
    tris = []
    for j in range(2):
        for i in range(8):
            a = j * 9 + i
            tris += [[a, a + 1, a + 10], [a, a + 10, a + 9]]
    mesh = EMMesh(pts, tris, np.full(len(tris), 201))
    rows = np.arange(len(tris))
    return mesh, magnetisation_forces(mesh, rows, np.tile(b, (len(rows), 1)), mu_r=mu_r, axisymmetric=False)


def test_slab_in_a_uniform_field_is_pulled_at_its_faces():
    """B = 1 T across the 4 x 1 mm slab: ½ (ν0 − ν) B² outwards on its top and bottom faces (4 mm long) and
    ½ (μ − μ0) (ν B)² outwards on its end faces (1 mm, the field along them); B along the slab: the same with
    the faces exchanged. The net force vanishes (a uniform field pulls no body)."""
    mu_r, nu = 500.0, 1 / (MU0 * 500.0)
    across, along = 0.5 * (1 / MU0 - nu), 0.5 * (MU0 * mu_r - MU0) * nu ** 2   # N/m^2 at B = 1 T
    for b, y_faces, x_faces in (((0.0, 1.0), across * 4e-3, along * 1e-3), ((1.0, 0.0), along * 4e-3, across * 1e-3)):
        mesh, (nodes, f) = _slab(mu_r, b)
        x, y = mesh.points[nodes].T
        assert f[y == 1e-3, 1].sum() == pytest.approx(y_faces, rel=1e-12)
        assert f[y == 0.0, 1].sum() == pytest.approx(-y_faces, rel=1e-12)
        assert f[x == 4e-3, 0].sum() == pytest.approx(x_faces, rel=1e-12)
        assert f[x == 0.0, 0].sum() == pytest.approx(-x_faces, rel=1e-12)
        assert np.allclose(f.sum(axis=0), 0.0, atol=1e-12 * y_faces)


def test_vacuum_has_no_magnetisation_force():
    """μ_r = 1: every nodal force is 0.0 exactly (whatever B), and a model in vacuum gives None: the Lorentz
    force alone reaches the mechanics."""
    rng = np.random.default_rng(1)
    mesh, _ = _slab(1.0, (0.0, 1.0))
    rows = np.arange(len(mesh.triangles))
    _, f = magnetisation_forces(mesh, rows, rng.normal(size=(len(rows), 2)), mu_r=1.0, axisymmetric=True)
    assert np.all(f == 0.0)
    model = EMModel(axisymmetric=True, coils=[Coil(1, waveform=DampedSine(1.0, 0.0, 1.0))], conductors=[Conductor(3e7)])
    assert model_magnetisation_forces(model, mesh.points, mesh.triangles, None) is None


def _disk_run(work, h: float, z0: float, core: MagneticCore, ni: float):
    mesh = coil_conductor_mesh([COIL], [], cores=[Rect(0.0, z0, RADIUS, z0 + THICK)], r_domain=0.1, r_shell=0.125,
                               h_fine=h, h_coarse=0.01)
    model = EMModel(axisymmetric=True, coils=[Coil(turns=100, waveform=DampedSine(ni / 100, 0.0, 0.0, math.pi / 2))],
                    cores=[core], shell=(0.1, 0.125), newton_tolerance=1e-10)
    solver = GetDPSolver(model, work / f"z{z0:.6f}")
    res, _ = solver.step(mesh, solver.initial_state(), 1e-3, field_output=True)
    return mesh, res


def _coenergy(mesh, res, core: MagneticCore) -> float:
    rows = np.flatnonzero(mesh.tri_tags == core_tag(1))
    h_of_b, w_of_b = material_laws(core.mu_r, core.bh_curve)
    b = np.hypot(*res.b_cells[rows].T)
    return float(res.magnetic_energy[-1] + np.sum((h_of_b(b) * b - 2 * w_of_b(b)) * element_volumes(mesh, rows, True)))


def _maxwell_stress_z(mesh, b_cells, d: float, n: int = 4000) -> float:
    """F_z from the air's Maxwell stress on the contour d around the disk (axis side: r = 0, no contribution)."""
    from matplotlib.tri import Triangulation

    finder = Triangulation(mesh.points[:, 0], mesh.points[:, 1], mesh.triangles).get_trifinder()
    total = 0.0
    lo, hi, r1 = Z0 - d, Z0 + THICK + d, RADIUS + d
    for a, b, normal in (((0.0, lo), (r1, lo), (0.0, -1.0)), ((r1, lo), (r1, hi), (1.0, 0.0)),
                         ((r1, hi), (0.0, hi), (0.0, 1.0))):
        s = (np.arange(n) + 0.5) / n
        p = np.asarray(a)[None] + s[:, None] * (np.asarray(b) - np.asarray(a))[None]
        bb = b_cells[finder(p[:, 0], p[:, 1])]
        nn = np.asarray(normal)
        tz = ((bb @ nn) * bb[:, 1] - 0.5 * (bb ** 2).sum(axis=1) * nn[1]) / MU0
        total += float(np.sum(tz * 2 * np.pi * p[:, 0])) * math.dist(a, b) / n
    return total


def _three_ways(work, h: float, core: MagneticCore, ni: float) -> tuple[float, float, float, float]:
    """(surface force, Maxwell stress at 0.5 mm, at 1 mm, virtual work): F_z on the disk (N)."""
    mesh, res = _disk_run(work, h, Z0, core, ni)
    rows = np.flatnonzero(mesh.tri_tags == core_tag(1))
    _, f = magnetisation_forces(mesh, rows, res.b_cells[rows], mu_r=core.mu_r, curve=core.bh_curve, axisymmetric=True)
    dz = 1e-4
    w = [_coenergy(*_disk_run(work, h, Z0 + s * dz, core, ni), core) for s in (1, -1)]
    return float(f[:, 1].sum()), _maxwell_stress_z(mesh, res.b_cells, 5e-4), _maxwell_stress_z(mesh, res.b_cells, 1e-3), \
        (w[0] - w[1]) / (2 * dz)


@pytest.fixture(scope="module")
def linear_disk(tmp_path_factory):
    """The three forces of the linear disk (μ_r = 1000, 2000 A-turns, 0.25 mm triangles at the boundaries)."""
    return _three_ways(tmp_path_factory.mktemp("disk"), 2.5e-4, MagneticCore(mu_r=1000.0), 2e3)


@needs_getdp
@pytest.mark.getdp
def test_iron_disk_attraction_three_ways(linear_disk):
    """μ_r = 1000, 2000 A-turns, 0.25 mm triangles at the boundaries (7.7k): the Maxwell stress on both contours
    within 1 % of virtual work (observed −0.48 % and −0.08 %), the surface force within 1.5 % (observed −1.26 %;
    −1.9 % at 0.5 mm, −1.1 % at 0.125 mm: first order in h, from B of the body's boundary triangles)."""
    surf, mst1, mst2, vw = linear_disk
    assert vw < 0   # pulled towards the coil (z < 0)
    assert mst1 == pytest.approx(vw, rel=0.01) and mst2 == pytest.approx(vw, rel=0.01)
    assert surf == pytest.approx(vw, rel=0.015)


@needs_getdp
@pytest.mark.getdp
@pytest.mark.slow
def test_saturated_iron_disk_attraction_three_ways(work):
    """The curve STEEL at 40 kA-turns (the disk saturates; Newton 10 solves), 0.125 mm (15.9k triangles): the
    Maxwell stress within 1 % of virtual work (observed −0.55 %, −0.75 %), the surface force within 1.5 %
    (observed −1.15 %)."""
    surf, mst1, mst2, vw = _three_ways(work, 1.25e-4, MagneticCore(bh_curve=STEEL), 4e4)
    assert mst1 == pytest.approx(vw, rel=0.01) and mst2 == pytest.approx(vw, rel=0.01)
    assert surf == pytest.approx(vw, rel=0.015)


@needs_getdp
@pytest.mark.getdp
def test_iron_disk_attraction_3d_sector(work, linear_disk):
    """The same disk in 3D (a 30° sector, tetrahedra of 1 mm in the disk, 12.5k; a conductor of σ = 1e-3 S/m:
    its Lorentz force is nil): the surface force on the sector's faces (the meridian planes are no surface),
    times 12, within 3.5 % of the axisymmetric virtual work (observed −2.8 %; −4.1 % at 2 mm, −2.0 % at 0.6 mm:
    first order in h)."""
    from pulseform.solvers.getdp.magnetic_force import no_surface
    from pulseform.solvers.getdp.mesh3d import ring_sector_mesh
    from pulseform.solvers.getdp.solver3d import Coil3D, EM3DModel, solve_transient3d

    mesh = ring_sector_mesh(work / "disk3d.msh", COIL, [Rect(0.0, Z0, RADIUS, Z0 + THICK)], sector_deg=30.0,
                            r_air=0.1, r_shell=0.125, h_coil=2e-3, h_conductor=1e-3, h_air=0.015)
    model = EM3DModel(coils=[Coil3D(100, waveform=DampedSine(20.0, 0.0, 0.0, math.pi / 2))],
                      conductors=[Conductor(1e-3, mu_r=1000.0)], shell=(0.1, 0.125), sector_deg=30.0)
    res = solve_transient3d(model, mesh, 1e-3, 1, work / "run3d")
    mag = model_magnetisation_forces(model, mesh.points, mesh.tets, res, no_surface(mesh))
    vw = linear_disk[3]
    assert 12 * mag[:, 2].sum() == pytest.approx(vw, rel=0.035)
    assert abs(12 * res.conductor_force[-1, 0, 2]) < 1e-6 * abs(vw)
