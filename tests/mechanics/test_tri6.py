"""Six-node triangles (``BodySpec.element = "tri6"``, issue 34 item 4, the 2D half): the element's pieces (shape
functions, Gauss rule, HRZ mass, consistent edge pressure, the explicit kernel against the implicit update in plane
stress, plane strain and axisymmetry, the tangent, the critical step against the mesh's largest frequency, the
ledger of a free vibration) and what it was chosen for: a plane-stress cantilever with three elements through its
thickness against beam theory (tests/mechanics/cantilever_strip.py), and the axisymmetric thick cylinder against
Lamé."""
import math

import numpy as np
import pytest
import scipy.linalg as sla
from dolfinx import mesh as dmesh
from mpi4py import MPI

from cantilever_strip import (Strip, beam_deflection, beam_plastic_deflection, beam_runaway, hinge_load,
                              plane_strip_body, relax_to_rest, runaway, static_levels, tip_deflection, tip_load)
from mech_helpers import central_difference_tangent
from pulseform.solvers.dolfinx import BodySpec, ExplicitSolver, ImplicitOptions, ImplicitSolver, Material
from pulseform.solvers.dolfinx.implicit_element import CellState, cell_tangent, cell_update
from pulseform.solvers.dolfinx.kernels import (MODE_AXISYMMETRIC, MODE_PLANE_STRAIN, MODE_PLANE_STRESS,
                                               pack_parameters)
from pulseform.solvers.dolfinx.tet10 import quadratic_cells
from pulseform.solvers.dolfinx.tri6 import (EDGES, QP_DERIVATIVES, QP_VALUES, QP_WEIGHTS, edge_pressure_forces,
                                            hrz_lumped_mass, qp_measures, shape_derivatives, shape_values)
from pulseform.solvers.dolfinx.tri6_kernel import tri6_step

E, NU = 200e9, 0.3
G, K = E / (2 * (1 + NU)), E / (3 * (1 - 2 * NU))
ELASTIC = Material(7800.0, G, K, 1e12, 0.0)
STEEL = Material(7800.0, G, K, 300e6, 1e9)


def _cells(seed=1, jitter=1e-5, shift=2e-3):
    """Three six-node cells around a shared vertex, edge nodes moved off the midpoints (curved cells), at
    r >= ``shift`` (m)."""
    rng = np.random.default_rng(seed)
    X = np.array([[0, 0], [1, 0], [1.2, 1], [0, 1.1], [-0.8, 0.2]]) * 1e-3 + [shift, 0.0]
    c = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 4]])
    c6, X6, _ = quadratic_cells(c, X, EDGES)
    return c6, X6 + jitter * rng.standard_normal(X6.shape), rng


def test_shape_functions_quadrature_hrz_mass_and_edge_pressure():
    """Partition of unity, nodal interpolation and linear completeness of the shape functions; the Gauss areas sum
    to the cell's; HRZ masses positive, a straight planar cell's corner 1/19 and edge node 16/57 of rho V, their sum
    the mass (axisymmetric: rho 2 pi r_c A, Pappus); a uniform pressure on a straight edge: 1/6, 1/6, 2/3 of its
    force, the ring's total 2 pi r_mid L p."""
    rng = np.random.default_rng(0)
    bary = rng.dirichlet(np.ones(3), size=5)
    assert np.abs(shape_values(bary).sum(axis=1) - 1).max() < 1e-14
    assert np.abs(shape_derivatives(bary).sum(axis=1)).max() < 1e-13
    c6, X6, _ = _cells(jitter=0.0)
    nodes_bary = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [.5, .5, 0], [0, .5, .5], [.5, 0, .5]])
    assert np.allclose(shape_values(nodes_bary), np.eye(6), atol=1e-14)
    xe = X6[c6[0]]
    assert np.allclose(np.einsum("ai,qaj->qij", xe, QP_DERIVATIVES),
                       np.stack([xe[1] - xe[0], xe[2] - xe[0]], axis=1)[None], rtol=1e-13)
    area = np.array([0.5 * abs(np.cross(X6[c[1]] - X6[c[0]], X6[c[2]] - X6[c[0]])) for c in c6])
    assert qp_measures(c6, X6, False, 2.0).reshape(3, 3).sum(axis=1) == pytest.approx(2.0 * area, rel=1e-13)
    m = hrz_lumped_mass(c6[:1], X6, 7800.0, False, 2.0)
    assert m[c6[0, 0]] == pytest.approx(7800.0 * 2.0 * area[0] / 19, rel=1e-12)
    assert m[c6[0, 3]] == pytest.approx(7800.0 * 2.0 * area[0] * 16 / 57, rel=1e-12)
    ma = hrz_lumped_mass(c6, X6, 7800.0, True, 1.0)
    rc = np.array([X6[c[:3], 0].mean() for c in c6])
    assert np.all(ma[np.unique(c6)] > 0) and ma.sum() == pytest.approx(7800.0 * np.sum(2 * np.pi * rc * area),
                                                                       rel=1e-12)
    edge = np.array([[0, 1, 5]])                        # a straight edge from (1, 0) to (1, 2) mm, middle node 5
    x = np.array([[1e-3, 0], [1e-3, 2e-3], [0, 0], [0, 0], [0, 0], [1e-3, 1e-3]])
    f = edge_pressure_forces(edge, x, 1e6, False, 0.5)
    assert f[[0, 1, 5], 0] == pytest.approx(-1e6 * 0.5 * 2e-3 * np.array([1, 1, 4]) / 6, rel=1e-13)
    fa = edge_pressure_forces(edge, x, 1e6, True, 1.0)
    assert fa[:, 0].sum() == pytest.approx(-1e6 * 2 * np.pi * 1e-3 * 2e-3, rel=1e-13)


@pytest.mark.parametrize("mode", [MODE_PLANE_STRESS, MODE_PLANE_STRAIN, MODE_AXISYMMETRIC])
def test_explicit_kernel_is_the_implicit_update_and_the_tangent_is_exact(mode):
    """One explicit step of the compiled kernel with v^{n+1/2} = du / dt and the implicit element's update with du
    give the same stress, plastic strain, plastic work and forces (to rounding: the two solvers share one element),
    every Gauss point yielding; the complex-step tangent equals central differences of the update."""
    c6, X6, rng = _cells(seed=mode)
    prm = pack_parameters(STEEL, mode, 0.01, 0.06, 1.2, False)
    v = 5.0 * rng.standard_normal(X6.shape)
    dt = 1e-6
    s0 = 1e8 * rng.standard_normal((9, 4))
    if mode == MODE_PLANE_STRESS:
        s0[:, 2] = 0.0
    s, ep, f, acc = s0.copy(), np.zeros(9), np.zeros_like(X6), np.zeros(3)
    tri6_step(c6, X6 + dt * v, v, dt, prm, s, ep, f, acc, np.empty(0), QP_DERIVATIVES, QP_VALUES, QP_WEIGHTS, 0.3)
    st = CellState(X6[c6], s0, np.zeros(9), STEEL, mode, 0.01, dt)
    du = (dt * v)[c6]
    r = cell_update(st, du)
    fi = np.stack([np.bincount(c6.ravel(), weights=r.force[:, :, k].ravel(), minlength=len(X6))
                   for k in range(2)], axis=1)
    assert np.all(r.deps_p > 0)
    assert np.abs(fi - f).max() <= 1e-12 * np.abs(f).max()
    assert np.abs(r.stress - s).max() <= 1e-12 * np.abs(s).max()
    assert np.abs(r.deps_p - ep).max() <= 1e-12 * ep.max()
    assert r.plastic_work.sum() == pytest.approx(acc[0], rel=1e-12)
    if mode != MODE_AXISYMMETRIC:                          # a planar cell's forces are in equilibrium
        assert np.abs(f.sum(axis=0)).max() <= 1e-12 * np.abs(f).max()
    Kc = cell_tangent(st, du)
    Kfd = central_difference_tangent(cell_update, st, du)
    assert Kc.shape == (3, 12, 12) and np.abs(Kc - Kfd).max() <= 1e-6 * np.abs(Kc).max()


def test_critical_step_bounds_the_largest_frequency():
    """The explicit solver's critical step of a six-node body (plane strain, CFL 1, no bulk viscosity) does not
    exceed 2 / omega_max of the assembled elastic stiffness and HRZ mass (scipy's dense eigensolver), and is
    within a factor two of it."""
    st = Strip(length=0.004, n_length=4, n_thick=2)
    kw = dict(formulation="plane_strain", thickness=0.005)
    s = ExplicitSolver([plane_strip_body(st, ELASTIC, "tri6")], bulk_viscosity=False, cfl=1.0, **kw)
    si = ImplicitSolver([plane_strip_body(st, ELASTIC, "tri6")], ImplicitOptions(dt=1.0, scheme="static"), **kw)
    b = si.bodies["strip"]
    Kt = si._assemble([("strip", b, si._cells("strip", b, np.zeros(b.cells.shape + (2,)), 1.0))], 0.0,
                      1.0).toarray()
    w2 = sla.eigh(0.5 * (Kt + Kt.T), np.diag(np.repeat(b.mass, 2)), eigvals_only=True)[-1]
    dt = s.stable_time_step()
    assert dt <= 2.0 / math.sqrt(w2) * (1 + 1e-12)
    assert dt >= 0.5 * 2.0 / math.sqrt(w2)


def test_free_vibration_ledger_balances():
    """A plane-stress strip set swinging (explicit, no bulk viscosity): the energy ledger (kinetic with the HRZ
    mass, elastic with the Gauss areas) balances to 1e-4 of the energy over 1000 steps, a third of it elastic."""
    st = Strip(length=0.01, n_length=5, n_thick=2)
    s = ExplicitSolver([plane_strip_body(st, ELASTIC, "tri6")], bulk_viscosity=False, thickness=0.005)
    b = s.bodies["strip"]
    b.v[:, 1] = 2.0 * (b.X0[:, 0] / st.length) ** 2          # a bending velocity field, m/s
    s._init_start()
    s.advance(s.stable_time_step(), 1000)
    e = s.energies()
    assert e["elastic_J"] > 0.3 * s.initial_energy
    assert abs(e["balance_error_J"]) <= 1e-4 * s.initial_energy


def _cantilever(st, element, material=ELASTIC, **options):
    s = ImplicitSolver([plane_strip_body(st, material, element)], ImplicitOptions(dt=1.0, scheme="static",
                                                                                  **options),
                       formulation="plane_stress", thickness=st.width)
    return s, s.bodies["strip"]


def test_cantilever_plane_stress_three_layers():
    """A 40 mm x 1 mm plane-stress cantilever (width 5 mm), 40 x 3 squares of two triangles: the static tip
    deflection of six-node triangles within 2 % of Euler-Bernoulli's P L^3 / (3 E I) + Timoshenko's shear term
    (measured 0.99995 of it, 1.0004 of Euler-Bernoulli); linear triangles on the same mesh lock: 0.416 of it
    (docs/mechanics.md; the test: below 1/2)."""
    st = Strip(width=0.005, n_length=40, n_thick=3)
    ratio = {}
    for element in ("tet4", "tri6"):
        s, b = _cantilever(st, element)
        s.advance(1.0, 1, {"strip": tip_load(b, st, 1.0)})
        ratio[element] = tip_deflection(b, st) / beam_deflection(st, ELASTIC, 1.0)
    assert ratio["tri6"] == pytest.approx(1.0, rel=0.02)
    assert ratio["tet4"] < 0.5


def test_thick_cylinder_under_internal_pressure_is_lame():
    """Axisymmetric thick cylinder (a = 10 mm, b = 20 mm, held axially: plane strain) under an internal pressure
    of 10 MPa on 10 x 2 six-node triangles: the radial displacement at the bore and at the outer surface within
    0.1 % of Lamé's u(r) = r / E (sigma_t - nu (sigma_r + sigma_z)) (measured: 3e-5 and 7e-5, the rest of the
    updated-Lagrangian's geometric terms at strains ~1e-4), and the hoop stress at every Gauss point within 1 % of
    Lamé's at its radius."""
    a, b, h, p = 0.01, 0.02, 0.002, 10e6
    msh = dmesh.create_rectangle(MPI.COMM_SELF, [np.array([a, 0.0]), np.array([b, h])], [10, 2])
    tol = 1e-9
    fixed = ((lambda x: (np.abs(x[1]) < tol) | (np.abs(x[1] - h) < tol), (1,)),)
    s = ImplicitSolver([BodySpec("ring", msh, ELASTIC, fixed=fixed, element="tri6")],
                       ImplicitOptions(dt=1.0, scheme="static"), formulation="axisymmetric")
    bd = s.bodies["ring"]
    s.advance(1.0, 1, {"ring": bd.pressure_forces(lambda x: np.abs(x[0] - a) < tol, p)})
    A, B = p * a ** 2 / (b ** 2 - a ** 2), p * a ** 2 * b ** 2 / (b ** 2 - a ** 2)

    def u(r):
        return r / E * (A + B / r ** 2 - NU * (A - B / r ** 2 + 2 * NU * A))

    for r0 in (a, b):
        on = np.abs(bd.X0[:, 0] - r0) < tol
        assert bd.u[on, 0].mean() == pytest.approx(u(r0), rel=1e-3)
    rq = np.einsum("qa,ca->cq", QP_VALUES, bd.X0[bd.cells][:, :, 0]).ravel()
    assert np.abs(bd.cell_stress[:, 2] / (A + B / rq ** 2) - 1).max() < 0.01


def test_element_choice_is_checked_and_fields_are_written(tmp_path):
    """'tri6' in 3D and 'tet10' in 2D are refused in one line (walls and contact with a six-node body are
    accepted: tests/mechanics/test_tri6_contact.py); a six-node body's field file holds its six-node cells and
    per-cell means of the Gauss points' stress."""
    import h5py

    from pulseform.solvers.dolfinx import ExplicitSolver3D, FieldWriter

    sq = dmesh.create_unit_square(MPI.COMM_SELF, 2, 2)
    box = dmesh.create_unit_cube(MPI.COMM_SELF, 1, 1, 1)
    with pytest.raises(ValueError, match="'tri6' is for 2D bodies"):
        ExplicitSolver3D([BodySpec("c", box, ELASTIC, (0.0, 0.0, 0.0), element="tri6")])
    with pytest.raises(ValueError, match="'tet10' is for 3D bodies"):
        ExplicitSolver([BodySpec("p", sq, ELASTIC, element="tet10")])
    s = ExplicitSolver([BodySpec("p", sq, ELASTIC, element="tri6")])
    b = s.bodies["p"]
    assert len(b.x) == 9 + 16 and b.cell_stress.shape == (8 * 3, 4)
    b.cell_stress[:] = np.arange(b.cell_stress.size, dtype=float).reshape(b.cell_stress.shape)
    with FieldWriter(s, tmp_path / "f") as fw:
        fw.write(0.0)
    with h5py.File(tmp_path / "f_p.h5") as h:
        assert h["Mesh/triangles6"].shape == (8, 6)
        assert h["Mesh/points"].shape == (25, 3)
        stress = h["Step_0000/stress_Pa"][...]
    assert np.allclose(stress[:, :4], b.cell_stress.reshape(-1, 3, 4).mean(axis=1))


@pytest.mark.slow
def test_cantilever_explicit_with_kinetic_damping():
    """The plane-stress strip (20 mm long, 20 x 3 squares) under a tip force, explicit with kinetic damping to
    rest: the tip deflection within 0.3 % of the implicit static solution on the same mesh and within 2 % of beam
    theory (Euler-Bernoulli + Timoshenko)."""
    st = Strip(length=0.02, width=0.005, n_length=20, n_thick=3)
    si, bi = _cantilever(st, "tri6")
    si.advance(1.0, 1, {"strip": tip_load(bi, st, 1.0)})
    d_implicit = tip_deflection(bi, st)
    s = ExplicitSolver([plane_strip_body(st, ELASTIC, "tri6")], cfl=0.8, formulation="plane_stress",
                       thickness=st.width)
    d = relax_to_rest(s, st, 1.0, d_implicit, 400)
    assert d == pytest.approx(d_implicit, rel=3e-3)
    assert d == pytest.approx(beam_deflection(st, ELASTIC, 1.0), rel=0.02)


@pytest.mark.slow
def test_cantilever_plastic_hinge_plane_stress():
    """The elastic-perfectly plastic plane-stress strip (40 x 1 mm, sigma_y 250 MPa; three six-node triangles
    through the thickness, 40 along crowded towards the root, x = L s^2) under static load steps: the load at which
    the tip deflection runs away (its compliance reaches ten times the elastic one) within 2 % of beam theory's
    (the rectangle's moment-curvature law, 0.9915 M_p / L by the same criterion; M_p / L = sigma_y b t^2 / (4 L));
    before the hinge the deflection follows beam theory within 2 % at 0.98 M_p / L."""
    st = Strip(width=0.001, n_length=40, n_thick=3, grading=2.0)
    mat = Material(7800.0, G, K, 250e6, 0.0)
    Pp = hinge_load(st, mat)
    s, _ = _cantilever(st, "tri6", mat, max_cuts=4)
    fr = np.round(np.arange(0.97, 1.0301, 0.005), 4)
    d = static_levels(s, st, fr * Pp)
    d_el = beam_deflection(st, mat, Pp, shear=False)
    assert d[2] == pytest.approx(beam_plastic_deflection(st, mat, 0.98 * Pp), rel=0.02)
    assert runaway(fr, np.array(d) / d_el) == pytest.approx(beam_runaway(st, mat), rel=0.02)
