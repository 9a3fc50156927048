"""Rigid walls and soft contact on six-node triangles (issue 34 item 4, the 2D half; solvers/dolfinx/tri6.py
``recover_edge_pressure``, Body.wall_pressures / contact_pressures, the face-by-face reading of
solvers/dolfinx/face_pressure.py).

References:

* a uniform pressure p on a straight three-node edge: its consistent nodal forces are p A / 6 at each corner and
  2 p A / 3 at the middle node in a planar body (int N_a ds of the quadratic edge; Zienkiewicz & Taylor, The Finite
  Element Method, vol. 1); a split in two halves gives p A / 4 and p A / 2. Either is read back as p at every node
  (exact to round-off), and so are the axisymmetric forces (int N_a 2 pi r ds: edge_pressure_forces);
* a bar pressed on a frictionless wall by an imposed end displacement d is in uniaxial stress sigma_xx =
  -E d / (L - d / 2) (the one-step Hughes-Winget strain, tests/mechanics/test_implicit_contact.py), the wall's
  pressure -sigma_xx on the current section at every node of the wall edge, corners included;
* two bars in series through the eq. (5) layer: the chain of test_implicit_contact.py;
* the paper's bar impact (section 4, plane stress): sigma = rho c v / 2 = 70 MPa, contact 2 L / c = 1.6 ms, on a
  sliding wall and across the soft layer; the linear triangles' tolerances (tests/mechanics/test_bar_impact.py):
  3 % on the plateau, 4 % on the duration, energy balance within 1 %.
"""
import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI
from scipy.optimize import brentq

from pulseform.solvers.dolfinx import BodySpec, ImplicitOptions, ImplicitSolver, Material
from pulseform.solvers.dolfinx.contact import ContactPairSpec, RigidWallSpec
from pulseform.solvers.dolfinx.tet10 import quadratic_cells
from pulseform.solvers.dolfinx.tri6 import EDGES, edge_pressure_forces, recover_edge_pressure
from pulseform.solvers.dolfinx.verification import PAPER_BAR_MATERIAL as MAT
from pulseform.solvers.dolfinx.verification import bar_impact

K_BULK, G = 58.3e9, 26.9e9
E = 9 * K_BULK * G / (3 * K_BULK + G)
ELASTIC = Material(2700.0, G, K_BULK, 1e12, 0.0)
L, H, T = 0.1, 0.01, 0.01
STATIC = ImplicitOptions(dt=1.0, scheme="static")
RHO_C_V_2 = MAT.density * MAT.bar_wave_speed * 10.0 / 2.0      # 70.0 MPa


@pytest.mark.parametrize("axisymmetric", [False, True], ids=["planar", "axisymmetric"])
@pytest.mark.parametrize("split", ["consistent", "halves"])
def test_uniform_pressure_is_read_at_every_node_of_three_node_edges(axisymmetric, split):
    """A uniform pressure's nodal forces on the straight edges x = 1.2 of a graded strip of six-node cells (edges
    of unequal length, r from 1 to 1.6 mm in axisymmetry): read back as p at every node of those edges to 1e-12,
    on a wall facing them too (projected areas)."""
    X = np.array([[1.0, 0.0], [1.2, 0.0], [1.0, 0.3], [1.2, 0.5], [1.0, 0.6], [1.2, 0.6]]) * 1e-3 + [1e-3, 0.0]
    c6, X6, _ = quadratic_cells(np.array([[0, 1, 3], [0, 3, 2], [2, 3, 5], [2, 5, 4]]), X, EDGES)
    right = np.flatnonzero(np.isclose(X6[:, 0], 2.2e-3))
    ends = np.array([[1, 3], [3, 5]])
    mid = [int(right[np.isclose(X6[right, 1], 0.5 * (X[a, 1] + X[b, 1]))][0]) for a, b in ends]
    edges3 = np.column_stack([ends, mid])
    p, t = 3e6, 2e-3
    if split == "consistent":
        f = -edge_pressure_forces(edges3, X6, p, axisymmetric, t)[:, 0]    # outward normal +x: push is -x
    else:
        f = np.zeros(len(X6))
        for a, b, m in edges3:
            half = np.abs(X6[b, 1] - X6[a, 1]) / 2
            for lo, hi in ((a, m), (m, b)):
                w = np.pi * (X6[lo, 0] + X6[hi, 0]) if axisymmetric else t
                f[[lo, hi]] += 0.5 * p * half * w
    nodes, pr = recover_edge_pressure(edges3, X6, f, axisymmetric, t)
    assert nodes.tolist() == np.unique(edges3).tolist()
    assert np.abs(pr / p - 1).max() < 1e-12
    nodes, pr = recover_edge_pressure(edges3, X6, f, axisymmetric, t, normal=np.array([-1.0, 0.0]))
    assert np.abs(pr / p - 1).max() < 1e-12


def _bar(x0, x1, nx=10, ny=2, fixed=()):
    msh = dmesh.create_rectangle(MPI.COMM_SELF, [np.array([x0, 0.0]), np.array([x1, H])], [nx, ny])
    return msh


def _at(x, y=None):
    if y is None:
        return lambda X: np.isclose(X[0], x)
    return lambda X: np.isclose(X[0], x) & np.isclose(X[1], y)


def test_implicit_six_node_bar_pressed_on_a_sliding_wall():
    """Plane stress, static: sigma_xx = -E d / (L - d/2) at every Gauss point to 1e-11, the wall's pressure
    -sigma_xx at all five nodes of the wall edge (corners and middles) to 1e-9."""
    d = 1e-5
    s = ImplicitSolver([BodySpec("bar", _bar(0.0, L), ELASTIC, element="tri6",
                                 fixed=((_at(L), (0,), -d), (_at(L, 0.0), (1,))))],
                       STATIC, formulation="plane_stress", thickness=T, comm=MPI.COMM_SELF,
                       rigid_walls=[RigidWallSpec((0.0, 0.0), (1.0, 0.0), sliding=True)])
    s.advance(1.0, 1)
    b = s.bodies["bar"]
    expect = -E * d / (L - d / 2)
    assert np.abs(b.cell_stress[:, 0] / expect - 1).max() < 1e-11
    rows, _, p = s.wall_pressure(0, "bar")
    face = np.flatnonzero(np.isclose(b.X0[:, 0], 0.0))
    assert np.sort(rows).tolist() == face.tolist() and len(face) == 5
    assert np.abs(p / -expect - 1).max() < 1e-9


def test_two_six_node_bars_pressed_through_the_soft_contact_layer():
    """Static, from inside the layer (g0 = 0.9 h0), three against two cells across (non-matching): Newton
    converges (to 1e-8 in at most 10 iterations), both bars' far-field stress equal (equilibrium, 1e-6) and within
    1 % of the analytic chain's (the layer's law acts at the half-segment nodes, not as the edge's consistent
    load, so the gap varies along the face: the chain holds for the force, not exactly for the layer's
    compliance)."""
    k, h0, d, g0 = 1e4, 1e-4, 1e-4, 0.9e-4
    La = L / 2
    a = BodySpec("a", _bar(0.0, La, 6, 2), ELASTIC, element="tri6", fixed=((_at(0.0), (0,)), (_at(0.0, 0.0), (1,))))
    b = BodySpec("b", _bar(La + g0, L + g0, 6, 3), ELASTIC, element="tri6",
                 fixed=((_at(L + g0), (0,), -d), (_at(L + g0, 0.0), (1,))))
    s = ImplicitSolver([a, b], STATIC, formulation="plane_stress", thickness=T, comm=MPI.COMM_SELF,
                       contact_pairs=[ContactPairSpec("b", "a", k, h0)])
    s.advance(1.0, 1)
    r = s.last_residuals
    print("Newton residuals", ", ".join(f"{v:.2g}" for v in r))
    assert r[-1] < 1e-8 and len(r) <= 10
    sig = brentq(lambda sg: 2 * sg * La / (E + sg / 2) + g0 - 1.0 / (sg / k + 1.0 / h0) - d, 1.0, 1e9)
    far = []
    for n, lo, hi in (("a", 0.0, La / 3), ("b", La + g0 + 2 * La / 3, L + g0)):
        bd = s.bodies[n]
        cx = bd.X0[bd.cells[:, :3]].mean(axis=1)[:, 0]
        sel = np.repeat((cx > lo) & (cx < hi), 3)        # equal-area cells, three equal-weight Gauss points
        far.append(float(bd.cell_stress[sel, 0].mean()))
    print("far-field stress / chain", far[0] / -sig, far[1] / -sig)
    assert far[0] == pytest.approx(far[1], rel=1e-6)
    assert far[0] == pytest.approx(-sig, rel=0.01)
    rows, _, p, _ = s.contact_pressure(0)
    assert rows.size == 7 and np.all(np.abs(p / sig - 1) < 0.05)


@pytest.mark.parametrize("wall", [True, False], ids=["sliding_wall", "two_bars"])
def test_six_node_bar_impact(wall):
    """The paper's bar impact on six-node triangles (20 x 10 cells, plane stress), explicit: on a sliding wall and
    across the soft layer, the contact stress at the face's middle within 3 % of rho c v / 2 (measured 69.87 and
    69.91 MPa), the contact's duration within 4 % of 2 L / c (1.554 and 1.567 ms), energy balance within 1 %
    (7e-4, 5e-4)."""
    r = bar_impact(nx=20, ny=10, rigid_wall=wall, wall_sliding=wall, element="tri6", comm=MPI.COMM_SELF)
    m = r["metrics"]
    assert m["contact_stress_plateau_MPa"] == pytest.approx(RHO_C_V_2 / 1e6, rel=0.03)
    assert m["contact_duration_ms"] == pytest.approx(1.6, rel=0.04)
    assert m["energy_error_rel"] < 0.01
