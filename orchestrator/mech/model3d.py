"""Translate a validated 3D case (``mechanics.formulation = "3d"``) into the explicit solver on
tetrahedra, :class:`~pulseform.solvers.dolfinx.solver3d.ExplicitSolver3D`: bodies meshed by gmsh
(:mod:`..mesh.solids`), symmetry planes as roller conditions, rigid walls, soft contact between
bodies (eq. (5), node to triangle face)."""

from __future__ import annotations

from typing import Callable

import numpy as np
from mpi4py import MPI

from pulseform.solvers import dolfinx as mech
from pulseform.solvers.dolfinx.solver3d import ExplicitSolver3D

from ..case.schema import SchemaError
from ..case.model import Case
from ..case.solid3d import SymmetryPlane
from ..mesh.solids import mesh_solid


def plane_marker(plane: SymmetryPlane, tol: float) -> Callable[[np.ndarray], np.ndarray]:
    """Marker of the nodes on ``plane``: |(x - point) . n| <= tol (m, n the unit normal), x given as (3, N)."""
    if plane.axis_aligned():
        c = plane.component()
        x0 = float(plane.point[c])
        return lambda x: np.abs(x[c] - x0) <= tol
    n = np.asarray(plane.normal, float) / np.linalg.norm(plane.normal)
    p0 = np.asarray(plane.point, float)
    return lambda x: np.abs(n @ (x - p0[:, None])) <= tol


def build_solver_3d(case: Case, comm: MPI.Comm = MPI.COMM_WORLD,
                    solver_material: Callable | None = None,
                    make_solver: Callable | None = None) -> ExplicitSolver3D:
    """Mesh every body with tetrahedra and build the 3D solver: symmetry planes hold the normal
    velocity of the nodes on them at zero (each body's own planes), walls are the case's
    (``solver_material``: case material table -> solver material; ``make_solver``: (case, bodies, pairs, walls,
    comm) -> the explicit or implicit solver, :func:`.model.make_solver`)."""
    bodies = []
    for i, b in enumerate(case.bodies):
        if b.element == "tet10" and comm.size > 1:
            raise SchemaError(f"bodies[{i}].element", f"got 'tet10' under MPI ({comm.size} processes); ten-node "
                              "tetrahedra run on one process for now: run without mpirun or set element = 'tet4'")
        mesh = mesh_solid(b.shape, b.mesh_size, comm, name=b.name, time_limit=case.limits.gmsh_time_limit_s)
        tol = 1e-9 * max(float(comm.allreduce(np.abs(mesh.geometry.x).max(initial=0.0), op=MPI.MAX)), 1.0)
        own = [s for s in case.symmetry if not s.bodies or b.name in s.bodies]
        # axis-aligned planes alone: rollers on one component; with an oblique one all of the body's
        # planes slide (a node on two planes then moves along their common line)
        aligned = all(s.axis_aligned() for s in own)
        fixed = tuple((plane_marker(s, tol), (s.component(),)) for s in own) if aligned else ()
        sliding = () if aligned else tuple((plane_marker(s, tol), tuple(s.normal)) for s in own)
        v0 = tuple(b.initial_velocity) if len(b.initial_velocity) == 3 else (0.0, 0.0, 0.0)
        bodies.append(mech.BodySpec(name=b.name, mesh=mesh, material=solver_material(case.materials[b.material]),
                                    initial_velocity=v0, fixed=fixed, sliding=sliding, element=b.element))
    walls = tuple(mech.RigidWallSpec(point=tuple(w.point), normal=tuple(w.normal),
                                     bodies=tuple(w.bodies) or None, sliding=w.sliding) for w in case.walls)
    pairs = tuple(mech.ContactPairSpec(slave=c.slave, master=c.master, stiffness=c.stiffness, h0=c.h0,
                                       friction=c.friction, viscosity=c.viscosity, two_pass=c.two_pass)
                  for c in case.contact)
    return make_solver(case, bodies, pairs, walls, comm)
