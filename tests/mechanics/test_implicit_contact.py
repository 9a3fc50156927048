"""Rigid walls and soft contact in the implicit solver (solvers/dolfinx/implicit_walls.py, implicit_contact.py;
issue 34, item 1).

References: a bar pressed on a frictionless (sliding) wall by an imposed end displacement d is in uniaxial
stress; the solver's one-step Hughes-Winget update strains it by d / (L - d / 2) (the increment's gradient on
the mid-step configuration), so sigma_xx = -E d / (L - d / 2) exactly, with no penalty error (the wall is an
exact constraint). Two bars in series through the soft-contact layer of eq. (5): the same stress in both bars,
p = k (1/h - 1/h0) = -sigma_xx, and d = 2 dl + (g0 - h) with dl = sigma L / (E + sigma / 2) the bars'
shortening: one equation for sigma (brentq).
"""
import math

import numpy as np
import pytest
import scipy.sparse as sp
from dolfinx import mesh as dmesh
from mpi4py import MPI
from scipy.optimize import brentq

from pulseform.solvers.dolfinx import BodySpec, ExplicitSolver, Material
from pulseform.solvers.dolfinx.contact import ContactPairSpec, RigidWallSpec
from pulseform.solvers.dolfinx.implicit import ImplicitOptions, ImplicitSolver, ImplicitSolver3D
from pulseform.solvers.dolfinx.implicit_contact import evaluate_contact

K_BULK, G = 58.3e9, 26.9e9
E = 9 * K_BULK * G / (3 * K_BULK + G)
ELASTIC = Material(2700.0, G, K_BULK, 1e12, 0.0)
L, H, T = 0.1, 0.01, 0.01
STATIC = ImplicitOptions(dt=1.0, scheme="static")


def _rect(x0, x1, nx=20, y0=0.0, y1=H, comm=MPI.COMM_SELF):
    return dmesh.create_rectangle(comm, [np.array([x0, y0]), np.array([x1, y1])], [nx, 2],
                                  diagonal=dmesh.DiagonalType.crossed)


def _at(x, y=None):
    if y is None:
        return lambda X: np.isclose(X[0], x)
    return lambda X: np.isclose(X[0], x) & np.isclose(X[1], y)


def test_bar_pressed_on_a_sliding_wall_carries_e_times_strain():
    """2D plane stress: sigma_xx = -E d / (L - d/2) in every cell to 1e-12 (measured 6e-15), and the wall's
    reaction (pressure x tributary area over the held nodes) is the bar's force sigma H' T on the current height
    H' (the Cauchy stress on the current section; plane stress keeps T)."""
    d = 1e-5
    s = ImplicitSolver([BodySpec("bar", _rect(0.0, L), ELASTIC, fixed=((_at(L), (0,), -d), (_at(L, 0.0), (1,))))],
                       STATIC, formulation="plane_stress", thickness=T, comm=MPI.COMM_SELF,
                       rigid_walls=[RigidWallSpec((0.0, 0.0), (1.0, 0.0), sliding=True)])
    s.advance(1.0, 1)
    sx = s.bodies["bar"].cell_stress[:, 0]
    expect = -E * d / (L - d / 2)
    assert np.abs(sx / expect - 1).max() < 1e-12
    b = s.bodies["bar"]
    hit, _, p = s.wall_pressure(0, "bar")
    area = b.wall_tributary_areas(b.x, np.array([1.0, 0.0]))[hit]
    assert np.sort(hit).tolist() == np.flatnonzero(np.isclose(b.X0[:, 0], 0.0)).tolist()
    height = np.ptp(b.x[np.isclose(b.X0[:, 0], 0.0), 1])
    assert float(np.sum(p * area)) == pytest.approx(-expect * height * T, rel=1e-10)


def test_a_sticking_wall_holds_its_nodes_as_a_support_does():
    """A sticking wall the bar rests on holds the nodes on it in every component: the same state as supports
    there, to round-off."""
    d = 1e-5
    push = (_at(L), (0,), -d)
    on_wall = ImplicitSolver([BodySpec("bar", _rect(0.0, L), ELASTIC, fixed=(push,))], STATIC,
                             formulation="plane_stress", thickness=T, comm=MPI.COMM_SELF,
                             rigid_walls=[RigidWallSpec((0.0, 0.0), (1.0, 0.0))])
    held = ImplicitSolver([BodySpec("bar", _rect(0.0, L), ELASTIC, fixed=(push, (_at(0.0), (0, 1))))], STATIC,
                          formulation="plane_stress", thickness=T, comm=MPI.COMM_SELF)
    on_wall.advance(1.0, 1)
    held.advance(1.0, 1)
    a, b = on_wall.bodies["bar"], held.bodies["bar"]
    assert np.abs(a.cell_stress - b.cell_stress).max() < 1e-9 * np.abs(b.cell_stress).max()
    assert np.abs(a.x - b.x).max() < 1e-15


def test_a_block_pressed_on_a_sliding_wall_in_3d():
    """3D tetrahedra: the same uniaxial stress on a wall x = 0 (sliding), the far face pushed by d."""
    d = 1e-5
    msh = dmesh.create_box(MPI.COMM_SELF, [np.array([0.0, 0.0, 0.0]), np.array([L, H, H])], [10, 2, 2])
    corner = lambda X: np.isclose(X[0], L) & np.isclose(X[1], 0.0) & np.isclose(X[2], 0.0)  # noqa: E731
    edge = lambda X: np.isclose(X[0], L) & np.isclose(X[1], 0.0) & np.isclose(X[2], H)  # noqa: E731
    s = ImplicitSolver3D([BodySpec("bar", msh, ELASTIC, initial_velocity=(0.0, 0.0, 0.0),
                                   fixed=((_at(L), (0,), -d), (corner, (1, 2)), (edge, (1,))))],
                         STATIC, comm=MPI.COMM_SELF,
                         rigid_walls=[RigidWallSpec((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), sliding=True)])
    s.advance(1.0, 1)
    sx = s.bodies["bar"].cell_stress[:, 0]
    assert np.abs(sx / (-E * d / (L - d / 2)) - 1).max() < 1e-11


def test_a_bar_released_from_the_wall_leaves_it():
    """Pressed on a sliding wall by ~1e-5 m over 5 ms, then the end pulled back by ~2e-5 m: the wall lets go of
    every node (no tensile reaction) and the bar leaves it."""
    s = ImplicitSolver([BodySpec("bar", _rect(0.0, L), ELASTIC,
                                 fixed=((_at(L), (0,), lambda t: -2e-3 if t < 5e-3 else 4e-3),
                                        (_at(L, 0.0), (1,))))],
                       ImplicitOptions(dt=1.0, scheme="trapezoidal"), formulation="plane_stress", thickness=T,
                       comm=MPI.COMM_SELF, rigid_walls=[RigidWallSpec((0.0, 0.0), (1.0, 0.0), sliding=True)])
    s.advance(1e-3, 5)      # the bar's first period is ~8e-5 s: dynamic, but slowly
    assert s.wall_pressure(0, "bar")[0].size == 3
    s.advance(1e-3, 5)
    assert s.wall_pressure(0, "bar")[0].size == 0
    assert s.bodies["bar"].x[:, 0].min() > 0.0


def _press(g0, d, k, h0, nx=10, yb=(0.0, H), comm=MPI.COMM_SELF):
    """Two bars of length L / 2 in series, g0 apart, the second (spanning ``yb``) pushed by d onto the first
    (contact pair); on ``comm`` (tests/mechanics/mpi_implicit_metrics.py: partitioned)."""
    La = L / 2
    a = BodySpec("a", _rect(0.0, La, nx, comm=comm), ELASTIC, fixed=((_at(0.0), (0,)), (_at(0.0, 0.0), (1,))))
    b = BodySpec("b", _rect(La + g0, 2 * La + g0, nx, *yb, comm=comm), ELASTIC,
                 fixed=((_at(2 * La + g0), (0,), -d), (_at(2 * La + g0, yb[0]), (1,))))
    return ImplicitSolver([a, b], STATIC, formulation="plane_stress", thickness=T, comm=comm,
                          contact_pairs=[ContactPairSpec("b", "a", k, h0)])


def chain_stress(g0, d, k, h0, length=L / 2):
    """The compressive stress (Pa) of the analytic chain: two bars of ``length`` (m), g0 apart, pressed by d
    through the layer (module docstring)."""
    return brentq(lambda sg: 2 * sg * length / (E + sg / 2) + g0 - 1.0 / (sg / k + 1.0 / h0) - d, 1.0, 1e9)


def test_two_bars_pressed_through_the_soft_contact_layer():
    """Static, from the layer's edge (g0 = h0): both bars carry the stress of the analytic chain to 1e-9
    (measured ~3e-13), the contact pressure is -sigma_xx at the layer's analytic gap, and Newton converges
    quadratically (the pair tangent is exact but for the contact area's change)."""
    k, h0, d = 1e4, 1e-4, 1e-4
    s = _press(h0, d, k, h0)
    s.advance(1.0, 1)
    sig = chain_stress(h0, d, k, h0)
    for n in ("a", "b"):
        sx = s.bodies[n].cell_stress[:, 0]
        assert np.abs(sx / -sig - 1).max() < 1e-9
    _, _, p, h = s.contact_pressure(0)
    assert p.size == 3
    assert np.abs(p / sig - 1).max() < 1e-9
    assert np.abs(h - 1.0 / (sig / k + 1.0 / h0)).max() < 1e-9 * h0
    r = s.last_residuals
    print("Newton residuals", ", ".join(f"{v:.2g}" for v in r))
    assert r[-1] < 1e-8 and len(r) <= 8
    assert r[-1] < r[-2] ** 1.5


def _press_3d(element, n_slave, g0, d, k, h0, comm=MPI.COMM_SELF):
    """Two 3D bars (L / 2 x H x H) in series, g0 apart, the second (``n_slave`` cells across, the first 2)
    pushed by d onto the first through the contact layer; each end face held in x, two of its nodes in y and z
    only as far as rigid motions need (the bars contract freely: uniaxial stress)."""
    La, v0 = L / 2, (0.0, 0.0, 0.0)

    def bar(x0, n):
        return dmesh.create_box(comm, [np.array([x0, 0.0, 0.0]), np.array([x0 + La, H, H])], [6, n, n])

    def ends(x, dx=None):
        face = ((lambda X: np.isclose(X[0], x)), (0,)) + ((dx,) if dx is not None else ())
        origin = lambda X: np.isclose(X[0], x) & np.isclose(X[1], 0.0) & np.isclose(X[2], 0.0)  # noqa: E731
        top = lambda X: np.isclose(X[0], x) & np.isclose(X[1], 0.0) & np.isclose(X[2], H)  # noqa: E731
        return (face, (origin, (1, 2)), (top, (1,)))

    a = BodySpec("a", bar(0.0, 2), ELASTIC, fixed=ends(0.0), element=element, initial_velocity=v0)
    b = BodySpec("b", bar(La + g0, n_slave), ELASTIC, fixed=ends(L + g0, -d), element=element, initial_velocity=v0)
    return ImplicitSolver3D([a, b], STATIC, comm=comm, contact_pairs=[ContactPairSpec("b", "a", k, h0)])


def _far_stress(body, lo, hi):
    """The volume mean of sigma_xx (Pa) over the cells whose centroid lies in lo < x < hi (m)."""
    nq = len(body.cell_stress) // len(body.cells)
    x = body.X0[body.cells[:, :4]]
    vol = np.abs(np.linalg.det(x[:, 1:] - x[:, :1]))
    cx = x.mean(axis=1)[:, 0]
    sel = (cx > lo) & (cx < hi)
    return float(np.sum(body.cell_stress.reshape(len(body.cells), nq, -1)[sel, :, 0].mean(axis=1) * vol[sel])
                 / vol[sel].sum())


@pytest.mark.parametrize("element", ["tet4", "tet10"])
def test_two_3d_bars_pressed_through_the_soft_contact_layer(element):
    """3D, static, from inside the layer (g0 = 0.9 h0), the analytic chain of the 2D test. Matching meshes of
    linear tetrahedra: every cell's stress and every node's contact pressure that of the chain to 1e-9
    (measured 3.5e-13), Newton quadratic. Ten-node bodies on non-matching faces (3 x 3 against 2 x 2 cells):
    the layer's law acts at every node of the quarter triangles of the six-node faces (the explicit solver's
    contact), whose shares are not the consistent loads of a uniform pressure (0 at corners, A / 3 at edge
    nodes), so the pressure and the gap vary over the face and the chain holds for the force carried, not the
    layer's compliance: both bars' far-field stress equal (equilibrium, to 1e-6) and within 1 % of the chain's
    (measured 0.54 % below). The regression: the slave nodes lying on the master's shared edges alternated
    between the two faces from one Newton iterate to the next (their normals tilt by ~1e-4 as the face
    deforms) and the residual stayed at 2.5e-6 (linear) / 5e-6 (ten-node) for 30 iterations
    (:func:`pulseform.solvers.dolfinx.contact.choose_faces`)."""
    k, h0, d, g0 = 1e4, 1e-4, 1e-4, 0.9e-4
    La = L / 2
    s = _press_3d(element, 2 if element == "tet4" else 3, g0, d, k, h0)
    s.advance(1.0, 1)
    sig = chain_stress(g0, d, k, h0)
    r = s.last_residuals
    print(element, "Newton residuals", ", ".join(f"{v:.2g}" for v in r))
    assert r[-1] < 1e-8 and len(r) <= 10
    far = [_far_stress(s.bodies["a"], 0.0, La / 3), _far_stress(s.bodies["b"], La + g0 + 2 * La / 3, L + g0)]
    print(element, "far-field stress / chain", far[0] / -sig, far[1] / -sig)
    if element == "tet4":
        for n in ("a", "b"):
            assert np.abs(s.bodies[n].cell_stress[:, 0] / -sig - 1).max() < 1e-9
        _, _, p, _ = s.contact_pressure(0)
        assert p.size == 9 and np.abs(p / sig - 1).max() < 1e-9
        assert r[-1] < r[-2] ** 1.5
    else:
        assert far[0] == pytest.approx(far[1], rel=1e-6)
        assert far[0] == pytest.approx(-sig, rel=0.01)


def test_contact_tangent_matches_finite_differences():
    """The assembled contact tangent against central differences of the contact forces (h = 1e-10 m) in the
    slave nodes' coordinates: along the contact normal (x) to 1e-6 of the largest entry (measured ~1e-8). Across
    it (y) the tangent leaves out the change of the slave node's contact area with the lengths of its segments,
    of relative size h / (segment length): bounded by 2 h / length (gap 4e-5 m, slave segments 3.5e-3 m).
    The master nodes' columns are not asserted: they differ by up to ~4 % in single entries (measured; not
    explained yet, see the issue's note)."""
    k, h0 = 1e4, 1e-4
    s = _press(0.4 * h0, 0.0, k, h0, nx=4, yb=(0.001, 0.008))    # slave nodes inside the master's segments
    x = {n: b.x.copy() for n, b in s.bodies.items()}
    ev = evaluate_contact(s, x)
    r, c, v = ev.tangent()
    K = sp.coo_matrix((v, (r, c)), shape=(s._ndof, s._ndof)).toarray()
    step = 1e-10
    worst = {0: 0.0, 1: 0.0}
    for j in np.unique(c[c >= s._offsets["b"]]):
        row, comp = divmod(j - s._offsets["b"], 2)
        f = []
        for sgn in (1, -1):
            xx = {m: a.copy() for m, a in x.items()}
            xx["b"][row, comp] += sgn * step
            e = evaluate_contact(s, xx)
            f.append(np.concatenate([e.force[m].ravel() for m in s.bodies]))
        fd = -(f[0] - f[1]) / (2 * step)
        worst[comp] = max(worst[comp], float(np.abs(fd - K[:, j]).max() / np.abs(K).max()))
    print(f"contact tangent vs central differences: {worst[0]:.2g} (x), {worst[1]:.2g} (y) of the largest entry")
    assert worst[0] < 1e-6
    assert worst[1] < 2 * 0.4 * h0 / 3.5e-3


def test_contact_friction_is_refused_in_one_line():
    """The velocity-dependent parts of the law are not in the implicit solver."""
    a = BodySpec("a", _rect(0.0, L / 2, 4), ELASTIC)
    b = BodySpec("b", _rect(L / 2 + 5e-5, L, 4), ELASTIC)
    with pytest.raises(ValueError, match="friction = 0 and viscosity = 0"):
        ImplicitSolver([a, b], STATIC, formulation="plane_stress", thickness=T, comm=MPI.COMM_SELF,
                       contact_pairs=[ContactPairSpec("b", "a", 1e4, 1e-4, friction=0.2)])


def test_a_slow_press_on_a_wall_matches_the_explicit_solver():
    """A bar 2 µm from a sliding wall, its far end pushed 12 µm by a sin^2 velocity over 2 ms (25 of its first
    periods: quasi-static), trapezoidal steps of 20 µs (100 steps) against the explicit solver (~10^4 steps): the
    mean stress within 1e-3 (measured 8e-5) and both within 1e-3 of the quasi-static -E (D - g) / L; the walls'
    forces within 1 % (measured: the implicit one is sigma H' T to 1e-3, the explicit one 0.75 % lower: the
    reaction of its last step's pushed nodes carries the bar's ringing)."""
    g, tend, dist = 2e-6, 2e-3, 1.2e-5
    vmax = 2 * dist / tend
    vel = lambda t: -vmax * math.sin(math.pi * min(t, tend) / tend) ** 2  # noqa: E731
    wall = [RigidWallSpec((0.0, 0.0), (1.0, 0.0), sliding=True)]
    out = {}
    for kind in ("implicit", "explicit"):
        spec = BodySpec("bar", _rect(g, g + L), ELASTIC, fixed=((_at(g + L), (0,), vel), (_at(g + L, 0.0), (1,))))
        if kind == "implicit":
            s = ImplicitSolver([spec], ImplicitOptions(dt=2e-5, scheme="trapezoidal"), formulation="plane_stress",
                               thickness=T, comm=MPI.COMM_SELF, rigid_walls=wall)
            s.advance(2e-5, 100)
        else:
            s = ExplicitSolver([spec], formulation="plane_stress", thickness=T, comm=MPI.COMM_SELF, rigid_walls=wall)
            n = int(math.ceil(tend / s.stable_time_step()))
            s.advance(tend / n, n)
        b = s.bodies["bar"]
        hit, _, p = s.wall_pressure(0, "bar")
        force = float(np.sum(p * b.wall_tributary_areas(b.x, np.array([1.0, 0.0]))[hit]))
        out[kind] = (float(b.cell_stress[:, 0].mean()), force, np.ptp(b.x[np.isclose(b.X0[:, 0], g), 1]))
    (si, fi, hi), (se, fe, _) = out["implicit"], out["explicit"]
    print(f"mean stress {si / 1e6:.5f} vs {se / 1e6:.5f} MPa; wall force {fi:.2f} vs {fe:.2f} N")
    assert si == pytest.approx(se, rel=1e-3)
    for sx in (si, se):
        assert sx == pytest.approx(-E * (dist - g) / L, rel=1e-3)
    assert fi == pytest.approx(-si * hi * T, rel=1e-3)
    assert fi == pytest.approx(fe, rel=0.01)
