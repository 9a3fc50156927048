"""The coupled 3D path with a ten-node body (``element = "tet10"``, issue 34 item 4) on a tiny mesh, without getdp:
the force transfer onto the ten nodes, its choice of shares, and the EM mesh moving with the body's vertex rows
(orchestrator/coupling/transfer3d.py, ``ConductorBody3D``, the loop with the analytic load of
orchestrator/coupling/fakes.py).

References: (1) conservation by construction: the HRZ shares sum to one, so Σ nodal forces = Σ f V (round-off),
and their first moment is the straight cell's centroid, so Σ x_i F_i = Σ c_e f_e V_e (round-off; checked
against the cells' centroids computed independently from their corners); (2) the choice of shares, measured: a
uniform force density f on a free body must give every node the acceleration f / rho (the continuum translates
rigidly: no strain). The HRZ shares do so exactly (F_i / m_i = f / rho to round-off), and an explicit run of the
free body under them stores no elastic energy (round-off of the kinetic); the consistent quadratic weights
(∫ N_i dV / V: a corner -1/20, an edge node 1/5) accelerate the corners backwards (-1.8 f / rho) and the same run
stores a large fraction of its kinetic energy as strain (printed); (3) the loop: the EM mesh's body nodes are the
body's vertex rows after every step (round-off), the ledger of every EM step at round-off; (4) Joule heat: the EM
elements match the body's corner cells one to one, and a cell's heat e raises its Gauss points by e / (rho c_p)
(the adiabatic law, to round-off).
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from pulseform.orchestrator.coupling.fakes import AnalyticLorentz3D
from pulseform.orchestrator.coupling.loop import LoopOptions, StaggeredLoop
from pulseform.orchestrator.coupling.transfer3d import TEN_NODE_SHARES, body_forces, ten_node_forces, tet_force_integral
from pulseform.orchestrator.em.conductor3d import ConductorBody3D
from pulseform.orchestrator.mech.participants import DolfinxMechanics
from pulseform.orchestrator.mesh.motion3d import MeshMover3D, nodes_on_plane
from pulseform.orchestrator.mesh.shared3d import conductor_submesh3d, match_nodes3d, to_dolfinx3d
from pulseform.solvers import dolfinx as mech
from pulseform.solvers.dolfinx.solver3d import ExplicitSolver3D
from pulseform.solvers.getdp import Rect
from pulseform.solvers.getdp.mesh import COIL_BASE, conductor_tag
from pulseform.solvers.getdp.mesh3d import ring_sector_mesh, tet_volumes

SECTOR = 5.0
RHO = 2700.0
#: the consistent quadratic weights ∫ N_i dV / V of a straight ten-node cell: a corner -1/20, an edge node 1/5
CONSISTENT = np.concatenate([np.full(4, -1.0 / 20.0), np.full(6, 1.0 / 5.0)])


@pytest.fixture(scope="module")
def ring(tmp_path_factory):
    """(EM mesh, its conductor's submesh, explicit solver of the ten-node disk, ConductorBody3D)."""
    path = tmp_path_factory.mktemp("m3d10") / "sector.msh"
    turns = [Rect(0.012 + i * 0.006, -0.004, 0.016 + i * 0.006, -0.001) for i in range(2)]
    mesh = ring_sector_mesh(path, turns, [Rect(0.0, 0.0, 0.03, 0.001)], sector_deg=SECTOR, h_coil=4e-3,
                            h_conductor=3e-3, h_air=0.03, conductor_layers=2)
    return (mesh, *_disk(mesh))


def _disk(mesh):
    sub = conductor_submesh3d(mesh, conductor_tag(1))
    material = mech.Material(density=RHO, shear_modulus=26.3e9, bulk_modulus=68.6e9, yield_stress=1e12,
                             hardening_modulus=0.0)
    solver = ExplicitSolver3D([mech.BodySpec(name="disk", mesh=to_dolfinx3d(sub, MPI.COMM_SELF), material=material,
                                             initial_velocity=(0.0, 0.0, 0.0), element="tet10")], comm=MPI.COMM_SELF, bulk_viscosity=False)
    body = solver.bodies["disk"]
    nodes = match_nodes3d(body.X0[:body.n_vertices], mesh.points, 1e-12)
    return sub, solver, ConductorBody3D("disk", conductor_tag(1), sub, nodes, cells10=body.cells)


def test_ten_node_transfer_is_conservative_and_keeps_the_moment(ring):
    mesh, sub, solver, cb = ring
    body = solver.bodies["disk"]
    # each cell's EM tetrahedron has the cell's corners
    assert np.array_equal(np.sort(mesh.tets[cb.em_rows], axis=1), np.sort(cb.body_to_em[body.cells[:, :4]], axis=1))
    rng = np.random.default_rng(3)
    f = rng.normal(size=(len(sub.rows), 3)) * 1e9 + np.array([0.0, 0.0, 4e9])   # N/m^3 on the EM rows sub.rows
    x = mesh.points
    forces = body_forces([cb], x, mesh.tets, sub.rows, f)["disk"]
    assert forces.shape == body.x.shape and len(body.x) > body.n_vertices
    integral = tet_force_integral(x, mesh.tets[sub.rows], f)
    err = np.abs(forces.sum(axis=0) - integral).max() / np.abs(integral).max()
    # first moment: Σ X_i ⊗ F_i over the nodes vs Σ c_e ⊗ f_e V_e over the cells (c_e from the EM corners)
    vol = tet_volumes(x, mesh.tets[sub.rows])
    moment_cells = np.einsum("ei,ej->ij", x[mesh.tets[sub.rows]].mean(axis=1), f * vol[:, None])
    moment_nodes = np.einsum("ni,nj->ij", body.X0, forces)
    err_m = np.abs(moment_nodes - moment_cells).max() / np.abs(moment_cells).max()
    print(f"\nten-node transfer: {len(body.cells)} cells, {len(body.x)} nodes; resultant {err:.1e}, "
          f"first moment {err_m:.1e}")
    assert err < 1e-13 and err_m < 1e-12
    assert TEN_NODE_SHARES.sum() == pytest.approx(1.0, abs=1e-15)


def test_hrz_shares_translate_a_free_body_under_a_uniform_force(ring):
    """The measurement behind the choice of shares (module docstring, (2))."""
    mesh, sub, _, cb = ring
    f0 = np.array([0.0, 0.0, 5e9])   # N/m^3
    f = np.tile(f0, (len(sub.rows), 1))
    ratios, energy = {}, {}
    for name, shares in (("hrz", TEN_NODE_SHARES), ("consistent", CONSISTENT)):
        _, solver, body_cb = _disk(mesh)
        b = solver.bodies["disk"]
        vol = tet_volumes(mesh.points, mesh.tets[body_cb.em_rows])
        nodal = ten_node_forces(body_cb.cells10, f[np.searchsorted(sub.rows, body_cb.em_rows)] * vol[:, None],
                                len(b.x), shares)
        assert np.allclose(nodal.sum(axis=0), f0 * vol.sum(), rtol=1e-13, atol=0.0)
        ratios[name] = nodal[:, 2] / b.mass / (f0[2] / RHO)
        dt = solver.stable_time_step()
        solver.advance(dt, 60, {"disk": nodal})
        e = solver.energies()
        energy[name] = e["elastic_J"] / e["kinetic_J"]
    print(f"\nuniform force on a free ten-node disk: a_i / (f / rho) HRZ {ratios['hrz'].min():.15f} .. "
          f"{ratios['hrz'].max():.15f}, consistent {ratios['consistent'].min():.3f} .. {ratios['consistent'].max():.3f}; "
          f"elastic / kinetic energy after 60 steps: HRZ {energy['hrz']:.1e}, consistent {energy['consistent']:.1e}")
    assert np.abs(ratios["hrz"] - 1.0).max() < 1e-12
    assert ratios["consistent"].min() == pytest.approx(-1.8, rel=1e-9)   # (-1/20) / (1/36)
    assert energy["hrz"] < 1e-12 and energy["consistent"] > 1e-3


def test_loop_moves_the_em_mesh_with_the_vertex_rows(ring, tmp_path):
    mesh, _, _, _ = ring
    sub, solver, cb = _disk(mesh)
    body = solver.bodies["disk"]
    held = (mesh.tet_tags > COIL_BASE) & (mesh.tet_tags < COIL_BASE + 100) | (mesh.tet_tags == conductor_tag(1))
    r = np.linalg.norm(mesh.points, axis=1)
    fixed = np.union1d(np.unique(mesh.tets[held]), np.flatnonzero(r >= r.max() * (1 - 1e-9)))
    a = math.radians(SECTOR)
    normals = [np.array([0.0, 1.0, 0.0]), np.array([-math.sin(a), math.cos(a), 0.0])]
    mover = MeshMover3D(mesh.points, mesh.tets, fixed, [(nodes_on_plane(mesh.points, (0, 0, 0), n, 1e-9), n)
                                                         for n in normals])

    def density(c, t):   # a bump at the disk's middle along +z, rising over 2 µs
        out = np.zeros_like(c)
        out[:, 2] = 2e10 * min(t / 2e-6, 1.0) * np.exp(-((np.hypot(c[:, 0], c[:, 1]) - 0.015) / 6e-3) ** 2)
        return out

    fake = AnalyticLorentz3D(mesh, [cb], mover, density)
    loop = StaggeredLoop(fake, DolfinxMechanics(solver), LoopOptions(n=20))
    rows = []
    loop.run_until(1.5e-6, on_em_step=rows.append)
    fake.follow(loop.mech.time, loop.mech)
    dev = float(np.abs(fake.x_em[cb.body_to_em] - body.x[:body.n_vertices]).max())
    u_edge = float(np.abs(body.x[body.n_vertices:] - body.X0[body.n_vertices:]).max())
    print(f"\nten-node disk, {len(rows)} EM steps: ledger {loop.counters.ledger_max:.1e}, EM nodes vs vertex rows "
          f"{dev:.1e} m, edge nodes moved {u_edge:.2e} m")
    assert len(rows) >= 2 and loop.counters.ledger_max < 1e-12
    assert dev < 1e-15 and u_edge > 0.0
    assert fake.last_forces["disk"].shape == body.x.shape


def test_joule_heat_reaches_the_gauss_points_of_a_ten_node_body(ring):
    """A ten-node body with a temperature: the EM elements match its corner cells, a cell's heat (J/m^3) raises each
    of its four Gauss points by e / (rho c_p), and its temperature for σ(T) is their mean."""
    from pulseform.orchestrator.em.joule_heat import cell_of_elements

    mesh, sub, _, _ = ring
    material = mech.Material(density=RHO, shear_modulus=26.3e9, bulk_modulus=68.6e9, yield_stress=1e12,
                             hardening_modulus=0.0, specific_heat=900.0)
    solver = ExplicitSolver3D([mech.BodySpec(name="disk", mesh=to_dolfinx3d(sub, MPI.COMM_SELF), material=material,
                                             initial_velocity=(0.0, 0.0, 0.0), element="tet10")], comm=MPI.COMM_SELF)
    body = solver.bodies["disk"]
    nodes = match_nodes3d(body.X0[:body.n_vertices], mesh.points, 1e-12)
    m = DolfinxMechanics(solver)
    cells = m.heated_cells()["disk"]
    assert cells.shape == (len(body.cells), 4)
    match = cell_of_elements(mesh.tets[sub.rows], nodes, cells)
    assert np.all(match >= 0) and len(np.unique(match)) == len(match)
    e = np.linspace(1e6, 2e6, len(body.cells))   # J/m^3 per cell
    t0 = body.temperature.copy()
    m.add_heat({"disk": e})
    np.testing.assert_allclose(body.temperature - t0, np.repeat(e, 4) / (RHO * 900.0), rtol=0.0, atol=1e-12)   # K: round-off of 293 K
    np.testing.assert_allclose(m.cell_temperatures()["disk"], t0[::4] + e / (RHO * 900.0), rtol=1e-15, atol=0.0)
