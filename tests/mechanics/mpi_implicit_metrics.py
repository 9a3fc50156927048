"""Run small implicit cases on MPI.COMM_WORLD (partitioned meshes) and print their metrics as JSON on rank 0:
probe displacements (m), the energy ledger (J), Newton iteration and cut counts, the largest plastic strain, the
wall time (s), and a restart's largest deviation from the uninterrupted run (m). Used by test_implicit_mpi.py
serially and under mpirun (the same cases; one process or a partition is the only difference).

Cases: an elastic-plastic plane-strain plate (cantilever) under a pressure ramp on its upper face (Newmark's
trapezoidal rule); an axisymmetric thick cylinder under a bore pressure ramp past yield (HHT, alpha = -0.1); a 3D
tet4 cantilever under a pressure on its upper face in three static steps past yield; a 3D block pressed on a
sliding rigid wall (static); a 2D bar pressed on a sliding wall and pulled back off it (trapezoidal: the wall's
active set takes nodes and lets them go); a restart of the plate after 4 of its 8 steps. By name only: the
one-line stops (``errors``), two 2D and two 3D bars pressed through the soft-contact layer of a contact pair
(``bars_contact2d``, ``bars_contact3d``).
"""
import json
import sys
import time

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI

from pulseform.solvers.dolfinx import BodySpec, Material
from pulseform.solvers.dolfinx.contact import RigidWallSpec
from pulseform.solvers.dolfinx.implicit import ImplicitOptions, ImplicitSolver, ImplicitSolver3D

COMM = MPI.COMM_WORLD
PLASTIC = Material(2700.0, 26e9, 70e9, 100e6, 500e6)
ELASTIC = Material(2700.0, 26.9e9, 58.3e9, 1e12, 0.0)
L, H, T = 0.1, 0.005, 0.01


def _probe(s, body, point) -> list:
    """The displacement (m) of the node at ``point`` (a mesh node), from the rank that owns it."""
    b = s.bodies[body]
    hit = np.flatnonzero(np.all(np.isclose(b.X0[:b.n_owned], np.asarray(point, float), atol=1e-12), axis=1))
    u = b.u[hit[0]] if hit.size else np.zeros(b.gdim)
    total = COMM.allreduce(u)
    assert COMM.allreduce(hit.size) == 1, f"probe {point} is not one node"
    return [float(v) for v in total]


def _reference(s, body, axis, value):
    """A facet marker of the nodes whose reference coordinate ``axis`` is ``value`` (m): the loaded face stays the
    same as the body moves (the marker gets the current coordinates)."""
    on = np.isclose(s.bodies[body].X0[:, axis], value, rtol=0.0, atol=1e-9)
    return lambda x: on


def _metrics(s, probes, t0) -> dict:
    out = {f"u_{name}_{c}": v for name, (body, p) in probes.items() for c, v in zip("xyz", _probe(s, body, p))}
    out.update({f"energy_{k}": float(v) for k, v in s.energies().items()})
    out["newton_iterations"] = s.newton_iterations
    out["step_cuts"] = s.step_cuts
    out["eps_p_max"] = COMM.allreduce(max((float(b.eps_p.max()) if b.eps_p.size else 0.0)
                                          for b in s.bodies.values()), op=MPI.MAX)
    out["wall_time_s"] = time.perf_counter() - t0
    return out


def _plate(options=None):
    msh = dmesh.create_rectangle(COMM, [np.array([0.0, 0.0]), np.array([L, H])], [20, 4],
                                 diagonal=dmesh.DiagonalType.crossed)
    return ImplicitSolver([BodySpec("plate", msh, PLASTIC, fixed=((lambda x: np.isclose(x[0], 0.0), (0, 1)),))],
                          options or ImplicitOptions(dt=2e-4), formulation="plane_strain", thickness=T, comm=COMM)


def _plate_steps(s, k0, k1):
    """Steps k0 .. k1 - 1 of 2e-4 s under the pressure 2.5e5 Pa x k / 8 on the upper face (follower; the first
    bending period is ~2.4 ms: the plate yields at the clamp)."""
    for k in range(k0, k1):
        f = s.pressure_nodal_forces("plate", _reference(s, "plate", 1, H), 2.5e5 * (k + 1) / 8)
        s.advance(2e-4, 1, {"plate": f})


def plate() -> dict:
    t0 = time.perf_counter()
    s = _plate()
    _plate_steps(s, 0, 8)
    return _metrics(s, {"tip": ("plate", (L, H)), "mid": ("plate", (L / 2, 0.0))}, t0)


def plate_restart() -> dict:
    """The plate's last 4 steps after a restart from the state after 4: the largest deviation (m, over all ranks)
    of the positions and of the velocities (m/s) from the uninterrupted run (0: the same bits)."""
    s1 = _plate()
    _plate_steps(s1, 0, 4)
    state = s1.state_dict()
    _plate_steps(s1, 4, 8)
    s2 = _plate()
    s2.load_state_dict(state)
    _plate_steps(s2, 4, 8)
    b1, b2 = s1.bodies["plate"], s2.bodies["plate"]
    return {"restart_dx_max": COMM.allreduce(float(np.abs(b1.x - b2.x).max()), op=MPI.MAX),
            "restart_dv_max": COMM.allreduce(float(np.abs(b1.v - b2.v).max()), op=MPI.MAX),
            "u_max": COMM.allreduce(float(np.abs(b1.u).max()), op=MPI.MAX),
            "v_max": COMM.allreduce(float(np.abs(b1.v).max()), op=MPI.MAX),
            "restart_same_energies": float(s1.energies() == s2.energies())}


def cylinder() -> dict:
    t0 = time.perf_counter()
    a, b_, h = 0.1, 0.2, 0.02
    msh = dmesh.create_rectangle(COMM, [np.array([a, 0.0]), np.array([b_, h])], [20, 4])
    ends = lambda x: np.isclose(x[1], 0.0) | np.isclose(x[1], h)  # noqa: E731
    s = ImplicitSolver([BodySpec("tube", msh, PLASTIC, fixed=((ends, (1,)),))],
                       ImplicitOptions(dt=2e-5, scheme="hht", alpha=-0.1), formulation="axisymmetric", comm=COMM)
    for k in range(10):
        f = s.pressure_nodal_forces("tube", _reference(s, "tube", 0, a), 80e6 * (k + 1) / 10)
        s.advance(2e-5, 1, {"tube": f})
    return _metrics(s, {"bore": ("tube", (a, 0.0)), "outer": ("tube", (b_, h))}, t0)


def cantilever3d() -> dict:
    t0 = time.perf_counter()
    msh = dmesh.create_box(COMM, [np.array([0.0, 0.0, 0.0]), np.array([0.1, 0.01, 0.01])], [12, 3, 3])
    s = ImplicitSolver3D([BodySpec("beam", msh, PLASTIC, initial_velocity=(0.0, 0.0, 0.0),
                                   fixed=((lambda x: np.isclose(x[0], 0.0), (0, 1, 2)),))],
                         ImplicitOptions(dt=1.0, scheme="static"), comm=COMM)
    for k in range(3):
        f = s.pressure_nodal_forces("beam", _reference(s, "beam", 2, 0.01), 1.5e6 * (k + 1) / 3)
        s.advance(1.0, 1, {"beam": f})
    return _metrics(s, {"tip": ("beam", (0.1, 0.0, 0.01)), "mid": ("beam", (0.05, 0.01, 0.0))}, t0)


def _at(x, y=None):
    if y is None:
        return lambda X: np.isclose(X[0], x)
    return lambda X: np.isclose(X[0], x) & np.isclose(X[1], y)


def block_on_wall3d() -> dict:
    t0 = time.perf_counter()
    d, Hb = 1e-5, 0.01
    msh = dmesh.create_box(COMM, [np.array([0.0, 0.0, 0.0]), np.array([L, Hb, Hb])], [10, 2, 2])
    corner = lambda X: np.isclose(X[0], L) & np.isclose(X[1], 0.0) & np.isclose(X[2], 0.0)  # noqa: E731
    edge = lambda X: np.isclose(X[0], L) & np.isclose(X[1], 0.0) & np.isclose(X[2], Hb)  # noqa: E731
    s = ImplicitSolver3D([BodySpec("block", msh, ELASTIC, initial_velocity=(0.0, 0.0, 0.0),
                                   fixed=((_at(L), (0,), -d), (corner, (1, 2)), (edge, (1,))))],
                         ImplicitOptions(dt=1.0, scheme="static"), comm=COMM,
                         rigid_walls=[RigidWallSpec((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), sliding=True)])
    s.advance(1.0, 1)
    out = _metrics(s, {"face": ("block", (0.0, Hb, Hb)), "end": ("block", (L, Hb, Hb))}, t0)
    hit, _, p = s.wall_pressure(0, "block")
    b = s.bodies["block"]
    own = hit < b.n_owned
    area = b.wall_tributary_areas(b.x, np.array([1.0, 0.0, 0.0]))
    area = b.complete_nodal(np.repeat(area[:, None], 3, axis=1))[:, 0]
    out["wall_force_N"] = COMM.allreduce(float(np.sum(p[own] * area[hit[own]])))
    out["sigma_xx_mean_Pa"] = COMM.allreduce(float(b.cell_stress[:, 0].sum())) / COMM.allreduce(len(b.cells))
    return out


def bar_off_wall2d() -> dict:
    t0 = time.perf_counter()
    msh = dmesh.create_rectangle(COMM, [np.array([0.0, 0.0]), np.array([L, 0.01])], [20, 2],
                                 diagonal=dmesh.DiagonalType.crossed)
    s = ImplicitSolver([BodySpec("bar", msh, ELASTIC,
                                 fixed=((_at(L), (0,), lambda t: -2e-3 if t < 5e-3 else 4e-3), (_at(L, 0.0), (1,))))],
                       ImplicitOptions(dt=1.0, scheme="trapezoidal"), formulation="plane_stress", thickness=T,
                       comm=COMM, rigid_walls=[RigidWallSpec((0.0, 0.0), (1.0, 0.0), sliding=True)])
    s.advance(1e-3, 5)
    b = s.bodies["bar"]
    held = COMM.allreduce(int(np.sum(s.wall_pressure(0, "bar")[0] < b.n_owned)))
    out = _metrics(s, {"wall": ("bar", (0.0, 0.01)), "mid": ("bar", (L / 2, 0.01))}, t0)
    out["held_nodes_pressed"] = held
    s.advance(1e-3, 5)
    out["held_nodes_released"] = COMM.allreduce(int(np.sum(s.wall_pressure(0, "bar")[0] < b.n_owned)))
    out.update({f"after_{k}": v for k, v in _metrics(s, {"wall": ("bar", (0.0, 0.01))}, t0).items()})
    return out


def errors() -> dict:
    """The one-line stops on every rank: a static step of an unsupported plate (SingularSystemError from the
    gathered rigid-motion check), a plastic static step allowed one Newton iteration and one cut
    (ImplicitConvergenceError), and the distributed LU of a zero tangent (SingularSystemError from MUMPS). Per
    error, the messages of all ranks (rank order) and whether the state stayed at t = 0."""
    import scipy.sparse as sp

    from pulseform.solvers.dolfinx.implicit import ImplicitConvergenceError, SingularSystemError

    def _stop(s, call):
        try:
            call()
            msg = None
        except (SingularSystemError, ImplicitConvergenceError) as exc:
            msg = f"{type(exc).__name__}: {exc}"
        return {"messages": COMM.allgather(msg), "time": s.time, "steps": s.step_count}

    msh = dmesh.create_rectangle(COMM, [np.array([0.0, 0.0]), np.array([L, H])], [10, 2],
                                 diagonal=dmesh.DiagonalType.crossed)
    free = ImplicitSolver([BodySpec("plate", msh, PLASTIC)], ImplicitOptions(dt=1.0, scheme="static"),
                          formulation="plane_strain", thickness=T, comm=COMM)
    out = {"unsupported": _stop(free, lambda: free.advance(1.0, 1))}
    s = _plate(ImplicitOptions(dt=1e-3, scheme="static", newton_max=1, max_cuts=1))
    f = s.pressure_nodal_forces("plate", _reference(s, "plate", 1, H), 2e6)
    out["newton"] = _stop(s, lambda: s.advance(1e-3, 1, {"plate": f}))
    lin = s._linear
    n = s._ndof
    lin.reduce(sp.identity(n, format="csr"), np.zeros(n), np.ones(n))
    out["zero_pivot"] = _stop(s, lambda: lin.solve(sp.csr_matrix((n, n)), 0.0, "a zero tangent"))
    return out


def _by_position(X0: np.ndarray, values: np.ndarray) -> list:
    """``values`` (owned rows of every rank) in the lexicographic order of the reference positions ``X0`` (m): the
    same order serially and on any partition."""
    X0 = np.concatenate(COMM.allgather(X0))
    values = np.concatenate(COMM.allgather(values))
    return values[np.lexsort(X0.T[::-1])].tolist()


def _plates(dim: int, g0: float, d: float, k: float, h0: float):
    """Two plates (L x H, 3D: L / 2 x H x H) stacked along y (3D: z), g0 apart, the upper one pushed down by d onto
    the lower one through the contact layer (static): the chain of test_implicit_contact.py pressed across the
    plates, whose contact face the partition cuts (a partition cuts the long direction; the bars' end faces lie
    in one part). The lower face of the lower plate and the upper face of the upper one held along the press, one
    corner of each in the other components and a second corner across (3D): uniaxial stress."""
    from pulseform.solvers.dolfinx.contact import ContactPairSpec

    ax = dim - 1
    lo, top = 2 * H + g0, H + g0
    near = lambda c, v: (lambda X: np.isclose(X[c], v))  # noqa: E731
    if dim == 2:
        def mesh(y0):
            return dmesh.create_rectangle(COMM, [np.array([0.0, y0]), np.array([L, y0 + H])], [20, 2],
                                          diagonal=dmesh.DiagonalType.crossed)

        def corners(y):
            return ((_at(0.0, y), (0,)),)
        cls, kw = ImplicitSolver, dict(formulation="plane_stress", thickness=T)
    else:
        def mesh(z0):
            return dmesh.create_box(COMM, [np.array([0.0, 0.0, z0]), np.array([L / 2, H, z0 + H])], [6, 2, 2])

        def corners(z):
            at = lambda x: (lambda X: np.isclose(X[0], x) & np.isclose(X[1], 0.0) & np.isclose(X[2], z))  # noqa
            return ((at(0.0), (0, 1)), (at(L / 2), (1,)))
        cls, kw = ImplicitSolver3D, {}
    zero = (0.0,) * dim
    a = BodySpec("a", mesh(0.0), ELASTIC, fixed=((near(ax, 0.0), (ax,)),) + corners(0.0), initial_velocity=zero)
    b = BodySpec("b", mesh(top), ELASTIC, fixed=((near(ax, lo), (ax,), -d),) + corners(lo), initial_velocity=zero)
    return cls([a, b], ImplicitOptions(dt=1.0, scheme="static"), comm=COMM,
               contact_pairs=[ContactPairSpec("b", "a", k, h0)], **kw)


def _bars_contact(dim: int, across: bool = False) -> dict:
    """Two bars pressed through the soft-contact layer (tests/mechanics/test_implicit_contact.py's 2D and 3D tet4
    chains, partitioned; ``across``: the plates of :func:`_plates`): the largest deviation of every cell's normal
    stress along the press and every slave node's contact pressure from the chain's stress, of the gaps from the
    chain's gap, the nodes in contact, the Newton residuals, the displacements of every node and the contact
    pressures in the order of the reference positions, the active pairs and how many of them each rank gives the
    tangent."""
    from pulseform.solvers.dolfinx.implicit_contact import evaluate_contact
    from test_implicit_contact import _press, _press_3d, chain_stress

    t0 = time.perf_counter()
    k, h0, d = 1e4, 1e-4, 1e-4
    g0 = h0 if dim == 2 else 0.9e-4
    if across:
        s, comp, sig = _plates(dim, g0, d, k, h0), dim - 1, chain_stress(g0, d, k, h0, length=H)
    else:
        s = _press(g0, d, k, h0, comm=COMM) if dim == 2 else _press_3d("tet4", 2, g0, d, k, h0, comm=COMM)
        comp, sig = 0, chain_stress(g0, d, k, h0)
    s.advance(1.0, 1)
    out = _metrics(s, {}, t0)
    out["stress_err_max"] = COMM.allreduce(max(float(np.abs(b.cell_stress[:, comp] / -sig - 1).max())
                                               for b in s.bodies.values()), op=MPI.MAX)
    gids, _, p, h = s.contact_pressure(0)      # every slave node in contact, the same on every rank
    X0 = s._surf["b"].X0[np.searchsorted(s._surf["b"].gids, gids)]
    out["contact_nodes"] = int(p.size)
    out["pressure_err_max"] = float(np.abs(p / sig - 1).max())
    out["gap_err_max_over_h0"] = float(np.abs(h - 1.0 / (sig / k + 1.0 / h0)).max() / h0)
    out["pressures_Pa"] = p[np.lexsort(X0.T[::-1])].tolist()
    out["residuals"] = list(s.last_residuals)
    ev = evaluate_contact(s, {n: b.x for n, b in s.bodies.items()})
    out["active_pairs"] = int(sum(len(si) for si, _ in ev.active.values()))
    out["tangent_pairs_per_rank"] = COMM.allgather(int(sum(len(pr[0]) for pr in ev._pairs)))
    for n, b in s.bodies.items():
        out[f"u_{n}_m"] = _by_position(b.X0[:b.n_owned], b.u[:b.n_owned])
    return out


CONTACT = {"bars_contact2d": lambda: _bars_contact(2), "bars_contact3d": lambda: _bars_contact(3),
           "plates_contact2d": lambda: _bars_contact(2, True), "plates_contact3d": lambda: _bars_contact(3, True)}

CASES = {"plate": plate, "plate_restart": plate_restart, "cylinder_hht": cylinder, "cantilever3d_static": cantilever3d,
         "block_on_wall3d": block_on_wall3d, "bar_off_wall2d": bar_off_wall2d}
#: run by name only (not part of the default set)
EXTRA = {"errors": errors, **CONTACT}

if __name__ == "__main__":
    names = sys.argv[1:] or list(CASES)
    result = {n: {**CASES, **EXTRA}[n]() for n in names}
    if COMM.rank == 0:
        json.dump(result, sys.stdout)
