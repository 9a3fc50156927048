"""The coupled 2D path with a six-node body (``element = "tri6"``, issue 34 item 4) on a tiny mesh, without getdp:
the force transfer onto the six nodes (orchestrator/coupling/transfer.py ``body_forces``), its choice of shares, the
conductor body's cells on the EM triangles (orchestrator/mesh/shared.py ``ConductorBody``), Joule heat to the Gauss
points and the forming-limit check on the corners; axisymmetric and planar.

References: (1) the choice of shares: a uniform force density f on a free body must give every node the
acceleration f / rho (the continuum translates rigidly). The HRZ shares do so to round-off (each cell's force
f V_e in the proportions of its nodes' HRZ masses, whose sum is rho V_e for a straight cell, so F_i = f m_i / rho),
r-weights included; an explicit run of the free planar body under them stores no elastic energy, while the
consistent quadratic weights (∫ N_i dA / A: a corner 0, an edge node 1/3) leave the corners behind and the same
run stores strain energy (printed); (2) conservation: the shares sum to one, so Σ nodal forces = Σ f V
(:func:`cell_force_integral`, computed independently) to round-off; the first moment Σ X_i ⊗ F_i equals
Σ c_e ⊗ f_e V_e with c_e the triangle's centroid from its corners (planar, round-off) or the ring's centroid
∫ x w dA / ∫ w dA (axisymmetric: the HRZ masses' first moment is not the ring's, the difference is O(h^2): measured
to fall by 4 when the cells halve); (3) a linear body's forces are the consistent ones as before, bit for bit;
(4) Joule heat: a cell's heat e raises its three Gauss points by e / (rho c_p); (5) the forming-limit check of a
homogeneous stretch reads the exact true strains.
"""
import numpy as np
import pytest
from mpi4py import MPI

from pulseform.orchestrator.coupling import transfer as tr
from pulseform.orchestrator.mech.participants import DolfinxMechanics
from pulseform.orchestrator.mesh.shared import ConductorBody, body_conductor, conductor_submesh, to_dolfinx
from pulseform.solvers import dolfinx as mech
from pulseform.solvers.getdp import EMMesh
from pulseform.solvers.getdp.mesh import conductor_tag

from .meshes import rect_mesh

RHO, CP = 2700.0, 900.0
TAG = conductor_tag(1)
DEPTH = 0.02   # m, the planar model's thickness


def em_mesh(nx: int, ny: int, r0: float = 0.01) -> EMMesh:
    """A 20 mm x 3 mm rectangle from r0 (m): a 1 mm sheet (tag TAG, y < 1 mm) under 2 mm of air (tag 1), jittered;
    its nodes shuffled so that the body's rows are not the EM mesh's."""
    x, cells = rect_mesh(nx, ny, r0, r0 + 0.02, 0.0, 0.003, jitter=0.2, seed=4)
    perm = np.random.default_rng(5).permutation(len(x))
    inv = np.argsort(perm)
    x, cells = x[perm], inv[cells]
    tags = np.where(x[cells, 1].mean(axis=1) < 0.001, TAG, 1)
    return EMMesh(x, cells, tags, np.zeros((0, 2), np.int64), np.zeros(0, np.int64))


def sheet(mesh: EMMesh, axisymmetric: bool, element: str = "tri6", thermal: bool = False):
    """(solver, ConductorBody) of the mesh's sheet as a free body."""
    sub = conductor_submesh(mesh, TAG)
    material = mech.Material(density=RHO, shear_modulus=26.3e9, bulk_modulus=68.6e9, yield_stress=1e12,
                             hardening_modulus=0.0, specific_heat=CP if thermal else None)
    solver = mech.ExplicitSolver([mech.BodySpec(name="sheet", mesh=to_dolfinx(sub, MPI.COMM_SELF), material=material,
                                                initial_velocity=(0.0, 0.0), element=element)],
                                 formulation="axisymmetric" if axisymmetric else "plane_strain", thickness=DEPTH,
                                 comm=MPI.COMM_SELF, bulk_viscosity=False)
    body = solver.bodies["sheet"]
    return solver, body_conductor("sheet", TAG, sub, body, mesh.points, 1e-12)


def scale(axisymmetric: bool) -> float:
    return 1.0 if axisymmetric else DEPTH


@pytest.mark.parametrize("axisymmetric", [True, False], ids=["axisymmetric", "planar"])
def test_uniform_force_density_accelerates_every_node_alike(axisymmetric):
    mesh = em_mesh(20, 6)
    solver, cb = sheet(mesh, axisymmetric)
    body = solver.bodies["sheet"]
    assert cb.cells6 is body.cells and len(body.x) == cb.n_nodes > len(cb.body_to_em)
    # each cell's EM triangle has the cell's corners
    corners = cb.body_to_em[body.cells[:, :3]]
    assert np.array_equal(np.sort(mesh.triangles[cb.em_rows], axis=1), np.sort(corners, axis=1))
    rows = cb.sub.rows
    f0 = np.array([3e9, -7e9])   # N/m^3
    forces = tr.body_forces([cb], mesh.points, mesh.triangles, rows, np.tile(f0, (len(rows), 1)),
                            axisymmetric=axisymmetric, scale=scale(axisymmetric))["sheet"]
    ratio = forces / body.mass[:, None] / (f0 / RHO)
    print(f"\nuniform force on a free six-node sheet ({'axisymmetric' if axisymmetric else 'planar'}): "
          f"a_i / (f / rho) {ratio.min():.15f} .. {ratio.max():.15f} over {len(body.x)} nodes")
    assert np.abs(ratio - 1.0).max() < 1e-12


def test_hrz_shares_translate_a_free_body_the_consistent_weights_shake_it():
    """Reference (1)'s run: 60 explicit steps of the free planar sheet under a uniform force density."""
    mesh = em_mesh(20, 6)
    f0 = np.array([0.0, 5e9])
    energy, ratios = {}, {}
    for name in ("hrz", "consistent"):
        solver, cb = sheet(mesh, False)
        b = solver.bodies["sheet"]
        shares = cb.shares if name == "hrz" else np.array([0, 0, 0, 1, 1, 1]) / 3.0
        v = DEPTH * tr.cell_volumes(mesh.points, mesh.triangles[cb.em_rows], axisymmetric=False)
        nodal = tr.share_forces(cb.cells6, f0 * v[:, None], shares, cb.n_nodes)
        assert np.allclose(nodal.sum(axis=0), f0 * v.sum(), rtol=1e-13, atol=0.0)
        ratios[name] = nodal[:, 1] / b.mass / (f0[1] / RHO)
        solver.advance(solver.stable_time_step(), 60, {"sheet": nodal})
        e = solver.energies()
        energy[name] = e["elastic_J"] / e["kinetic_J"]
    print(f"\nfree planar six-node sheet, uniform force: a_i / (f / rho) consistent "
          f"{ratios['consistent'].min():.3f} .. "
          f"{ratios['consistent'].max():.3f}; elastic / kinetic energy after 60 steps: HRZ {energy['hrz']:.1e}, "
          f"consistent {energy['consistent']:.1e}")
    # straight cells: a corner's consistent share 0 against its HRZ 1/19, an edge node's 1/3 against 16/57
    assert ratios["consistent"].min() == 0.0 and ratios["consistent"].max() == pytest.approx(57.0 / 48.0, rel=1e-12)
    assert energy["hrz"] < 1e-12 and energy["consistent"] > 1e-4   # round-off against strain (6.7e-4 measured)


def _ring_centroids(x: np.ndarray, tris: np.ndarray, axisymmetric: bool) -> np.ndarray:
    """∫ x w dA / ∫ w dA of each linear triangle (w = 2 pi r or 1), from the consistent P1 weights (exact)."""
    w = tr.nodal_volume_weights(x, tris, axisymmetric=axisymmetric)
    return np.einsum("ek,ekd->ed", w, x[tris]) / w.sum(axis=1)[:, None]


def _transfer_errors(nx: int, ny: int, axisymmetric: bool) -> tuple[float, float, int]:
    """(resultant, first moment) relative errors of the transfer of a random force density, and the cell count."""
    mesh = em_mesh(nx, ny)
    solver, cb = sheet(mesh, axisymmetric)
    body = solver.bodies["sheet"]
    rows, x = cb.sub.rows, mesh.points
    f = np.random.default_rng(3).normal(size=(len(rows), 2)) * 1e9 + np.array([0.0, 4e9])
    s = scale(axisymmetric)
    forces = tr.body_forces([cb], x, mesh.triangles, rows, f, axisymmetric=axisymmetric, scale=s)["sheet"]
    assert forces.shape == body.x.shape
    integral = s * tr.cell_force_integral(x, mesh.triangles[rows], f, axisymmetric=axisymmetric)
    err = np.abs(forces.sum(axis=0) - integral).max() / np.abs(integral).max()
    vol = s * tr.cell_volumes(x, mesh.triangles[rows], axisymmetric=axisymmetric)
    moment_cells = np.einsum("ei,ej->ij", _ring_centroids(x, mesh.triangles[rows], axisymmetric), f * vol[:, None])
    moment_nodes = np.einsum("ni,nj->ij", body.X0, forces)
    err_m = np.abs(moment_nodes - moment_cells).max() / np.abs(moment_cells).max()
    return err, err_m, len(body.cells)


def test_transfer_keeps_the_resultant_and_the_planar_first_moment():
    for axisymmetric in (False, True):
        err, err_m, nc = _transfer_errors(20, 6, axisymmetric)
        print(f"\nsix-node transfer ({'axisymmetric' if axisymmetric else 'planar'}, {nc} cells): resultant "
              f"{err:.1e}, first moment {err_m:.1e}")
        assert err < 1e-13
        if not axisymmetric:
            assert err_m < 1e-12


def test_axisymmetric_first_moment_error_falls_as_h_squared():
    """The HRZ masses' first moment differs from the ring's by O(h^2) per cell (module docstring, (2))."""
    e1 = _transfer_errors(10, 3, True)[1]
    e2 = _transfer_errors(20, 6, True)[1]
    e3 = _transfer_errors(40, 12, True)[1]
    print(f"\naxisymmetric first moment: {e1:.2e}, {e2:.2e}, {e3:.2e} (ratios {e1 / e2:.2f}, {e2 / e3:.2f})")
    assert e3 < 1e-4 and 3.0 < e2 / e3 < 5.0 and 3.0 < e1 / e2 < 5.0


@pytest.mark.parametrize("axisymmetric", [True, False], ids=["axisymmetric", "planar"])
def test_a_linear_body_gets_the_consistent_forces_bit_for_bit(axisymmetric):
    """What the GetDP load handed a linear body before six-node bodies: scale x the consistent P1 forces on the EM
    nodes, taken at the body's nodes (orchestrator/em/participant.py before this change)."""
    mesh = em_mesh(20, 6)
    _, cb = sheet(mesh, axisymmetric, element="tet4")
    assert cb.cells6 is None and cb.em_rows is None
    rows = cb.sub.rows
    f = np.random.default_rng(8).normal(size=(len(rows), 2)) * 1e9
    s = scale(axisymmetric)
    got = tr.body_forces([cb], mesh.points, mesh.triangles, rows, f, axisymmetric=axisymmetric, scale=s)["sheet"]
    want = (s * tr.cell_to_nodal_forces(mesh.points, mesh.triangles[rows], f, axisymmetric=axisymmetric))[cb.body_to_em]
    assert np.array_equal(got, want)


def test_a_linear_and_a_six_node_body_together():
    """Two bodies on the same EM step (a sheet and a die): each gets its own transfer; the ledger of both holds."""
    mesh = em_mesh(20, 6)
    top = mesh.points[mesh.triangles, 1].min(axis=1) > 0.002 - 1e-9
    mesh.tri_tags[top] = TAG + 1   # the air's upper half: a second conductor (no node shared with the sheet)
    solver, cb = sheet(mesh, True)
    sub2 = conductor_submesh(mesh, TAG + 1)
    die = ConductorBody("die", TAG + 1, sub2, sub2.em_nodes)
    rows = np.concatenate([cb.sub.rows, sub2.rows])
    f = np.random.default_rng(9).normal(size=(len(rows), 2)) * 1e9
    out = tr.body_forces([cb, die], mesh.points, mesh.triangles, rows, f, axisymmetric=True)
    integral = tr.cell_force_integral(mesh.points, mesh.triangles[rows], f, axisymmetric=True)
    total = out["sheet"].sum(axis=0) + out["die"].sum(axis=0)
    assert np.abs(total - integral).max() < 1e-13 * np.abs(integral).max()
    assert out["sheet"].shape == solver.bodies["sheet"].x.shape and out["die"].shape == (len(sub2.em_nodes), 2)


def test_joule_heat_reaches_the_gauss_points_of_a_six_node_body():
    """The EM triangles match the body's corner cells one to one; a cell's heat e (J/m^3) raises each of its three
    Gauss points by e / (rho c_p) (the adiabatic law); its temperature for σ(T) is their mean."""
    from pulseform.orchestrator.em.joule_heat import cell_of_elements

    mesh = em_mesh(20, 6)
    solver, cb = sheet(mesh, True, thermal=True)
    body = solver.bodies["sheet"]
    m = DolfinxMechanics(solver)
    cells = m.heated_cells()["sheet"]
    assert cells.shape == (len(body.cells), 3)
    match = cell_of_elements(mesh.triangles[cb.sub.rows], cb.body_to_em, cells)
    assert np.all(match >= 0) and len(np.unique(match)) == len(match)
    e = np.linspace(1e6, 2e6, len(body.cells))
    t0 = body.temperature.copy()
    m.add_heat({"sheet": e})
    np.testing.assert_allclose(body.temperature - t0, np.repeat(e, 3) / (RHO * CP), rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(m.cell_temperatures()["sheet"], t0[::3] + e / (RHO * CP), rtol=1e-15, atol=0.0)


def test_forming_limit_of_a_homogeneous_stretch_reads_the_true_strains():
    """x = (λ r, μ z): every corner triangle's in-plane strains are ln λ (meridian) and ln λ (hoop, r / r0 = λ), the
    thickness strain ln μ left out; the worst cell's centre is a cell's mean node."""
    from pulseform.orchestrator.mech.forming_limit import FormingLimitCurve, FormingLimitMonitor

    mesh = em_mesh(20, 6)
    solver, _ = sheet(mesh, True)
    b = solver.bodies["sheet"]
    lam, mu = 1.05, 0.93
    b.x[:] = b.X0 * np.array([lam, mu])
    curve = FormingLimitCurve(np.array([-0.2, 0.0, 0.2]), np.array([0.3, 0.2, 0.3]))
    monitor = FormingLimitMonitor({"sheet": curve}, solver)
    f = monitor.cell_fields("sheet")
    assert len(f["minor_strain"]) == len(b.cells)
    np.testing.assert_allclose(f["minor_strain"], np.log(lam), rtol=1e-12)
    np.testing.assert_allclose(f["major_strain"], np.log(lam), rtol=1e-12)
    row = monitor.record()
    assert row["sheet_flc_margin_min"] == pytest.approx(0.2 + 0.5 * np.log(lam) - np.log(lam), rel=1e-12)
